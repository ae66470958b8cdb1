#!/usr/bin/env python3
"""End-to-end test of springfitd's database through its clients: its mode, and its faults.

Usage: client_store_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts daemons on 127.0.0.1 with a free port in a temporary directory and checks: the SQLite
database's mode (0600), a cancel acknowledged just before a kill -9 (still cancelled after the
restart), a queued job's damaged row (quarantined, the jobs behind it run), and failing writes
(-32007, reads still answered, the daemon takes submissions again by itself). Python 3
standard library only (the shared part: client_support.py).

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import json
import os
import resource
import signal
import sqlite3
import stat
import sys
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree for harness.py
from harness import Conn, Daemon, R, error_data, require, short, wait_state  # noqa: E402
from client_support import (FINAL_STATES, JOB_TIMEOUT, expect_error, run_groups,  # noqa: E402
                            test_setup)


def file_mode(path):
    return stat.S_IMODE(os.stat(path).st_mode)


def test_db_mode(ctx):
    d = ctx.daemon("dbmode")
    with Conn(d.port) as c:  # a write, so that the WAL exists if the store uses one
        sub = c.result("job.submit", {"scene": ctx.small_scene, "label": "dbmode"})
        wait_state(c, sub["job"]["job_id"], FINAL_STATES, JOB_TIMEOUT)
    require(os.path.exists(d.db), f"no database file {d.db} (files: {os.listdir(d.dir)})")
    seen = []
    for path in (d.db, d.db + "-wal", d.db + "-shm"):
        if os.path.exists(path):
            seen.append(os.path.basename(path))
            mode = file_mode(path)
            R.expect(mode == 0o600, f"{os.path.basename(path)} created by springfitd --db: mode {mode:04o}, "
                                    f"expected 0600")
    # The main daemon's database, created in a fresh directory too.
    for path in (ctx.main.db, ctx.main.db + "-wal", ctx.main.db + "-shm"):
        if os.path.exists(path):
            mode = file_mode(path)
            R.expect(mode == 0o600, f"the main daemon's {os.path.basename(path)}: mode {mode:04o}, expected 0600")
    R.expect(os.path.basename(d.db) in seen, f"no database file among {seen}")


def test_durable_cancel(ctx):
    """A running job cancelled (acknowledged) and the daemon killed at once: after the restart
    the job is cancelled, not run again (issue 15: 8 of 8 such cancels were lost)."""
    d = ctx.daemon("cancel-kill")
    with Conn(d.port) as c:
        scene = json.load(open(ctx.kidney_path))
        scene.setdefault("search", {}).update({"strategy": "paper", "max_generations": 100000})
        job_id = c.result("job.submit", {"scene": scene, "label": "cancel-kill"})["job"]["job_id"]
        job = wait_state(c, job_id, ("running",) + FINAL_STATES, 10)
        require(job["state"] == "running", f"job {job_id} does not run: {short(job)}")
        answer = c.result("job.cancel", {"job_id": job_id})
        R.expect(answer.get("state") in ("cancelling", "cancelled"), f"job.cancel: {short(answer)}")
    d.kill9()  # right after the acknowledgement: the job may not have stopped yet
    d.start()
    with Conn(d.port) as c:
        job = wait_state(c, job_id, FINAL_STATES, 20)
        R.expect(job["state"] == "cancelled",
                 f"job {job_id} cancelled before a kill -9 is {job['state']} after the restart")
        trace = c.result("job.trace", {"job_id": job_id})
        R.expect(len(trace.get("rows", [])) < 100000, "the cancelled job ran to its end")


def test_failing_writes(ctx):
    """The database's writes failing (a file size limit of 1 byte: every write(2) fails with
    EFBIG, a real I/O error as a failing disk gives): submissions are answered -32007 saying
    so, never 'database disk image is malformed' (after one I/O error every answer said that,
    the file intact); reads still answer; the stored job stays intact; once writes succeed
    again the daemon takes submissions by itself (a new connection), without a restart."""
    d = Daemon(ctx.springfitd, ctx.tmp, "failing-writes", [],
               setup=lambda: signal.signal(signal.SIGXFSZ, signal.SIG_IGN))
    ctx.daemons.append(d)
    d.start()
    with Conn(d.port) as c:
        first = c.result("job.submit", {"scene": ctx.small_scene, "label": "before"})["job"]["job_id"]
        require(wait_state(c, first, FINAL_STATES, 30)["state"] == "succeeded", f"job {first} did not succeed")
        result_before = c.result("job.result", {"job_id": first})
        _, hard = resource.prlimit(d.proc.pid, resource.RLIMIT_FSIZE)
        resource.prlimit(d.proc.pid, resource.RLIMIT_FSIZE, (1, hard))
        try:
            for attempt in (1, 2):
                resp = c.call("job.submit", {"scene": ctx.small_scene, "label": f"during-{attempt}"})
                err = resp.get("error") or {}
                message = err.get("message", "")
                R.expect(err.get("code") == -32007 and "cannot be read or written" in message,
                         f"submission {attempt} with failing writes: {short(resp)}")
                R.expect("malformed" not in message, f"submission {attempt}: {message}")
            info = c.result("server.info")
            R.expect(info.get("name") == "springfitd", f"server.info with failing writes: {short(info)}")
            job = c.result("job.get", {"job_id": first})
            R.expect(job.get("state") == "succeeded", f"job {first} with failing writes: {short(job)}")
        finally:
            resource.prlimit(d.proc.pid, resource.RLIMIT_FSIZE, (hard, hard))
        created = c.result("job.submit", {"scene": ctx.small_scene, "label": "after"})
        R.expect(created.get("created") is True, f"submission after writes came back: {short(created)}")
        after = created["job"]["job_id"]
        R.expect(wait_state(c, after, FINAL_STATES, 30)["state"] == "succeeded", f"job {after} did not succeed")
        R.expect(c.result("job.result", {"job_id": first}) == result_before,
                 f"job {first}'s result changed across the failing writes")
        listed = [j["label"] for j in c.result("job.list", {})["jobs"]]
        R.expect(sorted(listed) == ["after", "before"], f"jobs after the failing writes: {listed}")

        # A running job whose progress writes fail for a while: it is neither failed nor lost,
        # and ends as it would have (its trace whole) once writes succeed again.
        scene = json.load(open(ctx.kidney_path))
        scene.setdefault("search", {}).update({"strategy": "paper", "max_seconds": 4})
        running = c.result("job.submit", {"scene": scene, "label": "running"})["job"]["job_id"]
        job = wait_state(c, running, ("running",) + FINAL_STATES, 10)
        require(job["state"] == "running", f"job {running} does not run: {short(job)}")
        time.sleep(1.0)
        resource.prlimit(d.proc.pid, resource.RLIMIT_FSIZE, (1, hard))
        try:
            time.sleep(2.0)
            job = c.result("job.get", {"job_id": running})
            R.expect(job["state"] in ("running", "queued"),
                     f"job {running} while its writes fail: {short(job)}")
        finally:
            resource.prlimit(d.proc.pid, resource.RLIMIT_FSIZE, (hard, hard))
        job = wait_state(c, running, FINAL_STATES, 60)
        R.expect(job["state"] == "succeeded", f"job {running} after its writes failed: {short(job)}")
        rows = c.result("job.trace", {"job_id": running, "limit": 10000})["rows"]
        generations = [r["generation"] for r in rows]
        R.expect(generations == list(range(len(generations))) and len(generations) > 1,
                 f"job {running}'s trace has holes: {short(generations)}")
    R.expect(d.alive(), "the daemon died of failing writes")
    R.expect("a new writing connection after an I/O error" in d.log_text(),
             f"no reopening in the log: {short(d.log_text()[-800:], 800)}")


def test_damaged_row(ctx):
    """A queued job whose row was damaged while the daemon was stopped (its progress column not
    JSON): the daemon starts all the same (it exited at start, issue 48), quarantines the job
    with one line in its log, runs the job queued behind it, and lists both, the damaged one
    apart as quarantined; reading it answers -32008 with the same incident every time."""
    d = ctx.daemon("damaged-row", ["--jobs", "1"])
    with Conn(d.port) as c:
        scene = json.load(open(ctx.kidney_path))
        scene.setdefault("search", {}).update({"strategy": "paper", "max_generations": 1000000})
        blocker = c.result("job.submit", {"scene": scene, "label": "blocker", "priority": 10})["job"]["job_id"]
        job = wait_state(c, blocker, ("running",) + FINAL_STATES, 10)
        require(job["state"] == "running", f"job {blocker} does not run: {short(job)}")
        damaged = c.result("job.submit", {"scene": ctx.small_scene, "label": "damaged", "priority": 5})["job"]["job_id"]
        good = c.result("job.submit", {"scene": ctx.small_scene, "label": "good"})["job"]["job_id"]
    require(d.stop(), "the daemon did not stop")
    db = sqlite3.connect(d.db)
    db.execute("UPDATE jobs SET progress = '{not json' WHERE id = ?", (damaged,))
    db.commit()
    db.close()
    d.start()
    with Conn(d.port) as c:
        c.result("job.cancel", {"job_id": blocker})
        job = wait_state(c, good, FINAL_STATES, 30)
        R.expect(job["state"] == "succeeded", f"the job behind the damaged one: {short(job)}")
        listed = c.result("job.list", {})
        R.expect([j["job_id"] for j in listed["jobs"]] == [blocker, good], f"job.list: {short(listed)}")
        quarantined = listed.get("quarantined") or [{}]
        R.expect(len(quarantined) == 1 and quarantined[0].get("job_id") == damaged
                 and quarantined[0].get("state") == "quarantined"
                 and "progress column" in quarantined[0].get("reason", ""),
                 f"job.list's quarantined: {short(listed)}")
        for read in (1, 2):
            err = expect_error(c.call("job.get", {"job_id": damaged}), -32008, f"job.get {read} of the damaged job")
            R.expect(error_data(err).get("incident") == quarantined[0].get("incident"),
                     f"job.get {read}: the incident is not the quarantine's: {short(err)}")
    R.expect(d.alive(), f"the daemon died: {short(d.log_text()[-800:], 800)}")
    lines = [l for l in d.log_text().splitlines() if f"job {damaged} quarantined" in l]
    R.expect(len(lines) == 1, f"the quarantine's lines in the log: {lines}")


if __name__ == "__main__":
    sys.exit(run_groups(sys.argv, __doc__, [
        ("setup", test_setup, True),
        ("database mode", test_db_mode, False),
        ("durable cancel", test_durable_cancel, False),
        ("damaged row", test_damaged_row, False),
        ("failing writes", test_failing_writes, False),
    ]))
