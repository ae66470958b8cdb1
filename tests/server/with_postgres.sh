#!/usr/bin/env bash
# Runs a command with a private PostgreSQL server: initdb into a temporary directory, a Unix
# socket in that directory only (no TCP port), stopped and removed at the end whatever the
# command's outcome. The command finds the server's URL in SPRINGFIT_TEST_PG_URL (database
# "postgres", user "springfit", trust authentication on the socket) and the directory in
# SPRINGFIT_TEST_PG_DIR. As root, the server runs as the "postgres" user (initdb refuses root).
#
#   with_postgres.sh COMMAND [ARGS...]
set -euo pipefail

bindir=""
for d in /usr/lib/postgresql/*/bin; do
  [ -x "$d/initdb" ] && bindir="$d"
done
if [ -z "$bindir" ]; then
  echo "with_postgres.sh: PostgreSQL's initdb is missing: run scripts/install-deps.sh" >&2
  exit 1
fi

dir=$(mktemp -d /tmp/springfit-pg.XXXXXX)
as_server=()
if [ "$(id -u)" -eq 0 ]; then
  chown postgres: "$dir"
  as_server=(runuser -u postgres --)
fi
chmod 700 "$dir"
stop() {
  "${as_server[@]}" "$bindir/pg_ctl" -D "$dir/data" -m immediate -w -t 20 stop >/dev/null 2>&1 || true
  rm -rf "$dir"
}
trap stop EXIT

"${as_server[@]}" "$bindir/initdb" -D "$dir/data" -U springfit --auth=trust -E UTF8 \
  --no-locale --no-sync >"$dir/initdb.log" 2>&1 || { cat "$dir/initdb.log" >&2; exit 1; }
# In the configuration, so that a test restarting the server (pg_ctl stop, start) gets the
# same one. fsync off: a test server is thrown away, never recovered after a power cut.
cat >>"$dir/data/postgresql.conf" <<CONF
listen_addresses = ''
unix_socket_directories = '$dir'
port = 5432
fsync = off
max_connections = 200
CONF
"${as_server[@]}" "$bindir/pg_ctl" -D "$dir/data" -l "$dir/server.log" -w -t 30 start >/dev/null \
  || { cat "$dir/server.log" >&2; exit 1; }

export SPRINGFIT_TEST_PG_DIR="$dir"
export SPRINGFIT_TEST_PG_BIN="$bindir"
export SPRINGFIT_TEST_PG_URL="postgresql:///postgres?host=$dir&port=5432&user=springfit"
set +e
"$@"
status=$?
set -e
exit $status
