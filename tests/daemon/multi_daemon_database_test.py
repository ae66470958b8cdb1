#!/usr/bin/env python3
"""Several springfitd daemons on one PostgreSQL database, from the outside: the database stopped
or frozen under them.

Usage: multi_daemon_database_test.py SPRINGFITD SPRINGFIT SOURCE_DIR
Run inside tests/server/with_postgres.sh, which starts a private PostgreSQL server and sets
SPRINGFIT_TEST_PG_URL (its URL), SPRINGFIT_TEST_PG_DIR and SPRINGFIT_TEST_PG_BIN.

Checks (each on a database of its own, every wait bounded):
  restart   the database stopped under running daemons: submits are refused with -32007 (never
            acknowledged), server.info still answers; the database back, the daemons resume on
            their own, and the interrupted job ends with the uninterrupted result
  stall     the database frozen (SIGSTOP) past the lease: server.info answers within 2 s with
            the store's error, and the job runs on once the server does, to the same result
Prints PASS/FAIL per check and exits non-zero on any failure (the shared part:
multi_daemon_support.py).
"""

import json
import os
import signal
import sys
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
from multi_daemon_support import (KIDNEY, LEASE, PAPER, PG_DIR, Daemon, fail,  # noqa: E402
                                  new_database, pg_ctl, rpc, run_checks, same_as_local, scene,
                                  stop_all, wait_checkpoint, wait_state)


def check_restart():
    url = new_database("restart")
    a = Daemon("restart-a", url)
    b = Daemon("restart-b", url)
    flags = ["--strategy", "paper", "--generations", "60", "--seed", "7"]
    job_id = int(a.cli("submit", KIDNEY, *flags).stdout.strip())
    if not wait_checkpoint(a, job_id, 3):
        fail("restart", f"job {job_id} reached no checkpoint")
    pg_ctl("stop", "-m", "fast")
    try:
        answer = rpc(a, "job.submit", {"scene": scene(PAPER), "idempotency_key": "while-down"})
        code = answer.get("error", {}).get("code")
        if code != -32007:
            fail("restart", f"a submit with the database down: {json.dumps(answer)[:300]}")
        info = rpc(b, "server.info")
        if "result" not in info or info["result"].get("queued") is not None:
            fail("restart", f"server.info with the database down: {json.dumps(info)[:300]}")
    finally:
        pg_ctl("start", "-l", os.path.join(PG_DIR, "server.log"))
    job = wait_state(a, job_id, ("succeeded", "failed", "cancelled"), 60)
    if job["state"] != "succeeded":
        fail("restart", f"job {job_id} after the database restart: {job['state']}")
    same_as_local("restart", a, job_id, KIDNEY, *flags)
    answer = rpc(b, "job.submit", {"scene": scene(PAPER), "idempotency_key": "while-down"})
    if not answer.get("result", {}).get("created"):
        fail("restart", f"the refused submit was stored after all: {json.dumps(answer)[:300]}")
    after = answer.get("result", {}).get("job", {}).get("job_id")
    if after is None or wait_state(a, after, ("succeeded",), 30)["state"] != "succeeded":
        fail("restart", "a job submitted after the restart did not run")
    stop_all()


def pg_pids():
    """The private server's processes: the postmaster (postmaster.pid's first line) and its
    children."""
    with open(os.path.join(PG_DIR, "data", "postmaster.pid")) as f:
        master = int(f.readline())
    children = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                ppid = int(f.read().rsplit(")", 1)[1].split()[1])  # after "pid (comm) state"
        except (OSError, ValueError, IndexError):
            continue
        if ppid == master:
            children.append(int(entry))
    return [master] + children


def check_stall():
    """PostgreSQL frozen (every process SIGSTOPped: the kernel still takes the bytes, so no
    socket error comes) past the lease: server.info answers within 2 s with the store's error,
    the job runs on once the server does, with the result of an uninterrupted run."""
    url = new_database("stall")
    a = Daemon("stall-a", url)
    flags = ["--strategy", "paper", "--generations", "60", "--seed", "11"]
    job_id = int(a.cli("submit", KIDNEY, *flags).stdout.strip())
    if not wait_checkpoint(a, job_id, 3):
        fail("stall", f"job {job_id} reached no checkpoint")
    pids = pg_pids()
    for pid in pids:
        os.kill(pid, signal.SIGSTOP)
    try:
        time.sleep(0.5)
        for attempt in (1, 2, 3):  # with the connection open, then reconnecting
            t0 = time.monotonic()
            info = rpc(a, "server.info")
            took = time.monotonic() - t0
            result = info.get("result", {})
            if took > 2.0 or result.get("queued") is not None or \
                    "did not answer within" not in result.get("store_error", ""):
                fail("stall", f"server.info {attempt} with the database frozen: {took:.2f} s, "
                              f"{json.dumps(info)[:300]}")
        time.sleep(LEASE + 1.0)
        if a.proc.poll() is not None:
            fail("stall", f"the daemon died while the database was frozen: {a.log()[-500:]}")
    finally:
        for pid in pids:
            os.kill(pid, signal.SIGCONT)
    job = wait_state(a, job_id, ("succeeded", "failed", "cancelled"), 90)
    if job["state"] != "succeeded":
        fail("stall", f"job {job_id} after the database woke: {job['state']} {job.get('error')}")
    else:
        same_as_local("stall", a, job_id, KIDNEY, *flags)
    info = rpc(a, "server.info").get("result", {})
    if info.get("queued") != 0 or "store_error" in info:
        fail("stall", f"server.info after the database woke: {info}")
    stop_all()


if __name__ == "__main__":
    run_checks([check_restart, check_stall])
