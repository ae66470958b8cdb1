#!/usr/bin/env python3
"""Outside-in test of springfitd under load: concurrent submissions with idempotency keys.

Usage: protocol_load_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts springfitd on 127.0.0.1 with a free port in a temporary directory and checks, against
the documented behaviour: the same idempotency key from six connections at once (one job), and
500 submissions from 50 concurrent clients, each retried with its key (500 distinct jobs, all
succeeded, job.list paging through them once each, in order). Python 3 standard library only
(the shared part: protocol_support.py).

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import os
import sys
import threading
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree for harness.py
from harness import IO_TIMEOUT, Abort, Conn, R, short  # noqa: E402
from protocol_support import run_groups, test_setup  # noqa: E402

# IO_TIMEOUT (5 s), START_TIMEOUT (10 s) and STOP_TIMEOUT (15 s) are harness.py's.
LOAD_THREADS = 50
LOAD_JOBS = 500
LOAD_DEADLINE = 40.0      # for all load jobs to be submitted and finished


def test_load(ctx):
    port = ctx.main.port
    nonce = f"{os.getpid()}-{time.time_ns()}"
    per_thread = LOAD_JOBS // LOAD_THREADS
    ids = [None] * LOAD_JOBS
    final = [None] * LOAD_JOBS
    errors = []
    errors_lock = threading.Lock()
    deadline = time.monotonic() + LOAD_DEADLINE
    start_barrier = threading.Barrier(LOAD_THREADS, timeout=IO_TIMEOUT * 2)

    def worker(t):
        try:
            with Conn(port) as c:
                start_barrier.wait()
                mine = range(t * per_thread, (t + 1) * per_thread)
                for i in mine:
                    params = {"scene": ctx.small_scene, "label": "load", "idempotency_key": f"load-{nonce}-{i}"}
                    first = c.result("job.submit", params)
                    if first.get("created") is not True:
                        raise Abort(f"job {i}: first submission created={first.get('created')!r}")
                    ids[i] = first["job"]["job_id"]
                    again = c.result("job.submit", params)
                    if again.get("created") is not False or again["job"].get("job_id") != ids[i]:
                        raise Abort(f"job {i}: retry with the same key gave created={again.get('created')!r} "
                                    f"job_id={again['job'].get('job_id')!r}, expected False and {ids[i]}")
                pending = set(mine)
                while pending:
                    if time.monotonic() > deadline:
                        raise Abort(f"{len(pending)} jobs unfinished after {LOAD_DEADLINE}s")
                    for i in sorted(pending):
                        job = c.result("job.get", {"job_id": ids[i]})
                        if job["state"] in ("succeeded", "failed", "cancelled"):
                            final[i] = job
                            pending.discard(i)
                    if pending:
                        time.sleep(0.25)
        except Exception as e:  # reported below, one line per thread
            with errors_lock:
                errors.append(f"thread {t}: {type(e).__name__}: {short(str(e))}")

    threads = [threading.Thread(target=worker, args=(t,), daemon=True) for t in range(LOAD_THREADS)]
    for th in threads:
        th.start()
    for th in threads:
        th.join(max(0.1, deadline - time.monotonic() + IO_TIMEOUT * 2))
    R.expect(not any(th.is_alive() for th in threads), "load threads still running at the deadline")
    for e in errors[:10]:
        R.fail(e)
    R.expect(len(errors) <= 10, f"... and {len(errors) - 10} more thread errors")
    submitted = [i for i in ids if i is not None]
    R.expect(len(submitted) == LOAD_JOBS and len(set(submitted)) == LOAD_JOBS,
             f"expected {LOAD_JOBS} distinct job ids, got {len(set(submitted))} of {len(submitted)}")
    states = {}
    for job in final:
        if job is not None:
            states[job["state"]] = states.get(job["state"], 0) + 1
    R.expect(states.get("succeeded") == LOAD_JOBS, f"expected {LOAD_JOBS} succeeded jobs, got {states}")

    # job.list with label "load", paged by 100.
    listed = []
    cursor = None
    pages = 0
    with Conn(port) as c:
        while pages < 20:
            params = {"label": "load", "limit": 100}
            if cursor is not None:
                params["cursor"] = cursor
            page = c.result("job.list", params)
            pages += 1
            R.expect(len(page["jobs"]) <= 100, f"a page of {len(page['jobs'])} jobs with limit 100")
            listed += page["jobs"]
            cursor = page.get("next_cursor")
            if cursor is None:
                break
    R.expect(cursor is None, f"job.list did not end within {pages} pages")
    listed_ids = [j["job_id"] for j in listed]
    R.expect(len(listed_ids) == len(set(listed_ids)), f"job.list returned duplicates: {len(listed_ids) - len(set(listed_ids))}")
    R.expect(set(listed_ids) == set(submitted) and len(listed_ids) == LOAD_JOBS,
             f"job.list label=load: {len(listed_ids)} jobs, {len(set(listed_ids) - set(submitted))} unknown, "
             f"{len(set(submitted) - set(listed_ids))} missing")
    R.expect(listed_ids == sorted(listed_ids), "job.list is not in submission order")
    R.expect(all(j.get("label") == "load" and j.get("state") == "succeeded" for j in listed),
             "job.list label=load: every job has label load and succeeded")


def test_idempotency_race(ctx):
    """The same idempotency key from several connections at once creates exactly one job."""
    port = ctx.main.port
    nonce = f"{os.getpid()}-{time.time_ns()}"
    keys = [f"race-{nonce}-{k}" for k in range(5)]
    answers = {k: [] for k in keys}
    lock = threading.Lock()

    def submit(key, barrier):
        try:
            with Conn(port) as c:
                barrier.wait()
                r = c.result("job.submit", {"scene": ctx.small_scene, "label": "race", "idempotency_key": key})
                with lock:
                    answers[key].append((r.get("created"), r["job"].get("job_id")))
        except Exception as e:
            with lock:
                answers[key].append(("error", f"{type(e).__name__}: {short(str(e))}"))

    for key in keys:
        barrier = threading.Barrier(6, timeout=IO_TIMEOUT)
        threads = [threading.Thread(target=submit, args=(key, barrier), daemon=True) for _ in range(6)]
        for th in threads:
            th.start()
        for th in threads:
            th.join(IO_TIMEOUT * 2)
        got = answers[key]
        R.expect(len(got) == 6 and sum(1 for c, _ in got if c is True) == 1 and
                 sum(1 for c, _ in got if c is False) == 5 and len({j for _, j in got}) == 1,
                 f"key {key} submitted 6 times at once: expected one created=true and one job id, got {got}")


if __name__ == "__main__":
    sys.exit(run_groups(sys.argv, __doc__, [
        ("setup", test_setup, True),
        ("idempotency race", test_idempotency_race, False),
        ("load", test_load, False),
    ]))
