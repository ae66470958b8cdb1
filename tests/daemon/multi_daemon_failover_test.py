#!/usr/bin/env python3
"""Several springfitd daemons on one PostgreSQL database, from the outside: a daemon's job taken
over by another when it is killed or paused.

Usage: multi_daemon_failover_test.py SPRINGFITD SPRINGFIT SOURCE_DIR
Run inside tests/server/with_postgres.sh, which starts a private PostgreSQL server and sets
SPRINGFIT_TEST_PG_URL (its URL), SPRINGFIT_TEST_PG_DIR and SPRINGFIT_TEST_PG_BIN.

Checks (each on a database of its own, every wait bounded):
  kill      kill -9 of the daemon running a job: another resumes it from its checkpoint once
            the lease expires, to the result and trace of an uninterrupted local run
  pause     a daemon paused (SIGSTOP) past its lease: another takes the job over, and the paused
            one, resumed, writes nothing more of it (its lease is lost); same result and trace
Prints PASS/FAIL per check and exits non-zero on any failure (the shared part:
multi_daemon_support.py).
"""

import signal
import sys

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
from multi_daemon_support import (KIDNEY, LEASE, Daemon, fail, new_database, rpc,  # noqa: E402
                                  run_checks, same_as_local, stop_all, wait_checkpoint, wait_log,
                                  wait_state)


def check_kill():
    url = new_database("kill")
    a = Daemon("kill-a", url)
    flags = ["--strategy", "paper", "--generations", "60", "--seed", "5"]
    job_id = int(a.cli("submit", KIDNEY, *flags).stdout.strip())
    if not wait_checkpoint(a, job_id, 5):
        fail("kill", f"job {job_id} reached no checkpoint on daemon A")
    b = Daemon("kill-b", url)
    a.kill(signal.SIGKILL)
    job = wait_state(b, job_id, ("succeeded", "failed", "cancelled"), 60)
    if job["state"] != "succeeded":
        fail("kill", f"job {job_id} after A's kill -9: {job['state']}")
    if "resumed from its checkpoint" not in b.log():
        fail("kill", "daemon B did not resume the job from its checkpoint")
    same_as_local("kill", b, job_id, KIDNEY, *flags)
    stop_all()


def check_pause():
    url = new_database("pause")
    a = Daemon("pause-a", url)
    flags = ["--strategy", "paper", "--generations", "60", "--seed", "6"]
    job_id = int(a.cli("submit", KIDNEY, *flags).stdout.strip())
    if not wait_checkpoint(a, job_id, 3):
        fail("pause", f"job {job_id} reached no checkpoint on daemon A")
    b = Daemon("pause-b", url)
    a.kill(signal.SIGSTOP)
    if not wait_log(b, "resumed from its checkpoint", LEASE + 20):
        fail("pause", "daemon B did not take the paused daemon's job over")
    a.proc.send_signal(signal.SIGCONT)
    job = wait_state(b, job_id, ("succeeded", "failed", "cancelled"), 60)
    if job["state"] != "succeeded":
        fail("pause", f"job {job_id}: {job['state']}")
    # A stops the job either way: its heartbeat finds the lease lost, or, when the freeze
    # caught it inside a store call, that call's watchdog fires first on waking, and its error
    # names the daemon's own stall (not a database that did not answer); the job goes back to
    # the store.
    if not wait_log(a, ("lease lost",
                        f"job {job_id} interrupted: the store call ran past its limit while this "
                        "daemon itself did not run"), 10):
        fail("pause", "the resumed daemon A did not stop the job (no lease lost, no watchdog)")
    if f"job {job_id} succeeded" in a.log():
        fail("pause", "the paused daemon ran the job to completion too")
    same_as_local("pause", b, job_id, KIDNEY, *flags)
    if rpc(a, "server.info").get("result", {}).get("daemon") != "pause-a":
        fail("pause", "daemon A does not answer after its pause")
    stop_all()


if __name__ == "__main__":
    run_checks([check_kill, check_pause])
