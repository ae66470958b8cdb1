#!/usr/bin/env python3
"""Several springfitd daemons on one PostgreSQL database, from the outside: jobs shared out.

Usage: multi_daemon_jobs_test.py SPRINGFITD SPRINGFIT SOURCE_DIR
Run inside tests/server/with_postgres.sh, which starts a private PostgreSQL server and sets
SPRINGFIT_TEST_PG_URL (its URL), SPRINGFIT_TEST_PG_DIR and SPRINGFIT_TEST_PG_BIN.

Checks (each on a database of its own, every wait bounded):
  load      3 daemons, 300 jobs from 30 clients, each submit retried through another daemon
            with its idempotency key: none lost, none duplicated, each run to completion once,
            the work spread over the daemons
  remote    job.watch and job.cancel through daemon A of a job daemon B runs
Prints PASS/FAIL per check and exits non-zero on any failure (the shared part:
multi_daemon_support.py).
"""

import json
import sys
import threading
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
from multi_daemon_support import (KIDNEY, PAPER, Conn, Daemon, fail, new_database, rpc,  # noqa: E402
                                  run_checks, scene, stop_all, wait_state)


def check_load():
    url = new_database("load")
    ds = [Daemon(f"load-{i}", url) for i in range(3)]
    ids, lock = {}, threading.Lock()
    errors = []

    def client(t):
        try:
            for i in range(10):
                key = f"load-{t}-{i}"
                params = {"scene": scene(PAPER), "label": "load", "seed": 1 + t * 10 + i,
                          "idempotency_key": key}
                first = rpc(ds[(t + i) % 3], "job.submit", params)["result"]
                retry = rpc(ds[(t + i + 1) % 3], "job.submit", params)["result"]
                if not first["created"] or retry["created"] or \
                        retry["job"]["job_id"] != first["job"]["job_id"]:
                    errors.append(f"{key}: {first['created']} {retry['created']}")
                with lock:
                    ids[key] = first["job"]["job_id"]
        except Exception as e:  # noqa: BLE001 - reported as a failure
            errors.append(f"client {t}: {e!r}")

    threads = [threading.Thread(target=client, args=(t,)) for t in range(30)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    for e in errors[:5]:
        fail("load", e)
    if len(set(ids.values())) != 300:
        fail("load", f"{len(set(ids.values()))} distinct jobs for 300 keys")
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        page = rpc(ds[0], "job.list", {"label": "load", "state": "succeeded", "limit": 1000})
        if len(page["result"]["jobs"]) >= len(ids):
            break
        time.sleep(0.25)
    listed = rpc(ds[1], "job.list", {"label": "load", "limit": 1000})["result"]["jobs"]
    states = {}
    for j in listed:
        states[j["state"]] = states.get(j["state"], 0) + 1
    if len(listed) != 300 or states.get("succeeded") != 300:
        fail("load", f"{len(listed)} jobs listed, states {states}")
    ran = {}
    for d in ds:
        for line in d.log().splitlines():
            if " succeeded (" in line:
                job_id = int(line.split(" job ")[1].split()[0])
                ran.setdefault(job_id, []).append(d.name)
    twice = {j: who for j, who in ran.items() if len(who) != 1}
    if twice:
        fail("load", f"jobs run to completion more than once: {list(twice.items())[:5]}")
    if len(ran) != 300:
        fail("load", f"{len(ran)} jobs logged as succeeded")
    per_daemon = {d.name: sum(1 for who in ran.values() if d.name in who) for d in ds}
    if sum(1 for n in per_daemon.values() if n > 0) < 2:
        fail("load", f"the jobs were not spread: {per_daemon}")
    print(f"load: 300 jobs, per daemon {per_daemon}", flush=True)
    stop_all()


def check_remote():
    url = new_database("remote")
    b = Daemon("remote-b", url)
    job_id = int(b.cli("submit", KIDNEY, "--strategy", "paper", "--generations", "100000")
                 .stdout.strip())
    wait_state(b, job_id, ("running",), 20)
    a = Daemon("remote-a", url)
    watch = Conn(a.port)
    answer = watch.call("job.watch", {"job_id": job_id})
    if answer.get("result", {}).get("state") != "running":
        fail("remote", f"job.watch through A: {json.dumps(answer)[:300]}")
    progress = watch.wait_notification(lambda n: n.get("method") == "job.progress", 10)
    if not progress or progress["params"].get("job_id") != job_id:
        fail("remote", "no job.progress through A of the job B runs")
    t0 = time.monotonic()
    cancel = rpc(a, "job.cancel", {"job_id": job_id})
    if cancel.get("result", {}).get("state") != "cancelling":
        fail("remote", f"job.cancel through A: {json.dumps(cancel)[:300]}")
    finished = watch.wait_notification(lambda n: n.get("method") == "job.finished", 10)
    took = time.monotonic() - t0
    if not finished or finished["params"].get("state") != "cancelled":
        fail("remote", f"no job.finished 'cancelled' through A: {finished}")
    elif took > 4.0:
        fail("remote", f"the cancel took {took:.1f} s to reach daemon B")
    watch.close()
    stop_all()


if __name__ == "__main__":
    run_checks([check_load, check_remote])
