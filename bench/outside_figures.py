#!/usr/bin/env python3
"""Re-measures the "outside figures" of the external robustness review of springfitd.

usage: /usr/bin/python3 bench/outside_figures.py [kill-loop|load|all] [--seed N]
       (run from anywhere; the binaries are taken from build/ next to this file)

kill-loop  M small jobs submitted (with idempotency keys, paced so that kills also hit
           submissions) while springfitd is killed with SIGKILL at random moments (seeded) and
           restarted on the same database, K times or until every job has finished. Then every
           acknowledged job must exist, have succeeded, and have the result and stored trace of
           the same scene+seed run on a second daemon that is never killed (proto/RPC.md,
           "Durability": equal but for wall times and cache_hits).
load       50 client threads each submit 10 small jobs and poll job.get until they finish:
           none may be lost; the latency of those job.get calls is reported.
(The hostile-corpus figure is tests/daemon/protocol_test.py's.)

Standard library only; reuses tests/daemon/harness.py (Conn, Daemon). Exit status 1 when a job
was lost or differed; the temporary directory (databases, daemon logs) is then kept.
"""
import argparse
import json
import os
import random
import shutil
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests", "daemon"))
from harness import Abort, Conn, Daemon  # noqa: E402

SPRINGFITD = os.path.join(ROOT, "build", "server", "springfitd")
FINAL = ("succeeded", "failed", "cancelled")
SCENES = ("paper-iso-5x5", "paper-aniso-5x5")  # 0.4-0.9 s a job with paper, 300 generations
# Jobs of < 1 s never reach the default 10 s checkpoint, so every kill would restart them from
# scratch; a short interval makes kills land after checkpoints and exercises the resume path.
DAEMON_FLAGS = ["--checkpoint-seconds", "0.1"]
# Not deterministic by design (proto/RUN.md, proto/RPC.md): wall times, the fitness cache,
# the thread count, the job's id in this database.
IGNORED = {"wall_seconds", "cache_hits", "seconds", "model_seconds", "threads", "job_id"}
NET_ERRORS = (OSError, Abort)  # refused/reset/timeout while the daemon is down or restarting


def load_scene(name):
    with open(os.path.join(ROOT, "examples", name + ".json")) as f:
        return json.load(f)


def job_scene(base, generations):
    scene = dict(base)
    scene["search"] = dict(base.get("search", {}), strategy="paper", max_generations=generations)
    return scene


def pct(values, p):
    """Nearest-rank percentile of a non-empty list."""
    s = sorted(values)
    return s[min(len(s) - 1, max(0, int(round(p / 100 * len(s) + 0.5)) - 1))]


def diff(a, b, path=""):
    """Paths where two JSON values differ, IGNORED keys left out (floats compared exactly)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            if k not in IGNORED and not k.endswith("_at"):
                out += diff(a.get(k, "<absent>"), b.get(k, "<absent>"), f"{path}.{k}")
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in diff(x, y, f"{path}[{i}]")]
    return [] if a == b and type(a) is type(b) else [f"{path}: {str(a)[:80]} != {str(b)[:80]}"]


def all_jobs(c):
    jobs, cursor = [], None
    while True:
        page = c.result("job.list", dict({"limit": 10000}, **({"cursor": cursor} if cursor else {})))
        jobs += page["jobs"]
        cursor = page["next_cursor"]
        if cursor is None:
            return jobs


def full_trace(c, job_id):
    rows, after = [], -1
    while after is not None:  # pages of 100 rows: the paging itself is under test
        page = c.result("job.trace", {"job_id": job_id, "after": after, "limit": 100})
        rows += page["rows"]
        after = page["next_after"]
    return rows


def wait_all_final(port, ids, timeout):
    """Polls job.list until every job of `ids` is final or absent (lost: the caller reports
    it); the jobs by id."""
    deadline = time.monotonic() + timeout
    with Conn(port) as c:
        while True:
            jobs = {j["job_id"]: j for j in all_jobs(c)}
            if all(jobs[i]["state"] in FINAL for i in ids if i in jobs) or time.monotonic() > deadline:
                return jobs
            time.sleep(0.25)


# --------------------------------------------------------------------------------------------
# 1. kill -9 loop


def kill_loop(tmp, args, problems):
    rng = random.Random(args.seed)
    bases = {n: load_scene(n) for n in SCENES}
    # (idempotency key, scene, seed): distinct seeds, the two scenes alternating.
    plan = [(f"kill-{i}", SCENES[i % 2], 1000 + i) for i in range(args.jobs)]

    def params(key, name, seed):
        return {"scene": job_scene(bases[name], args.generations), "seed": seed,
                "idempotency_key": key, "label": "kill-loop"}

    # The reference: the same jobs on a daemon that is never killed.
    t0 = time.monotonic()
    ref = Daemon(SPRINGFITD, tmp, "reference", DAEMON_FLAGS).start()
    try:
        with Conn(ref.port) as c:
            ref_ids = {key: c.result("job.submit", params(key, n, s), timeout=30)["job"]["job_id"]
                       for key, n, s in plan}
        ref_jobs = wait_all_final(ref.port, ref_ids.values(), 600)
        reference = {}
        with Conn(ref.port) as c:
            for key, jid in ref_ids.items():
                if ref_jobs.get(jid, {}).get("state") != "succeeded":
                    problems.append(f"reference job {key} (id {jid}): {ref_jobs.get(jid)}")
                    continue
                reference[key] = (c.result("job.result", {"job_id": jid}), full_trace(c, jid))
    finally:
        ref.stop()
    walls = [r["wall_seconds"] for r, _ in reference.values()]
    print(f"reference run: {len(reference)}/{len(plan)} jobs succeeded in {time.monotonic() - t0:.1f}s "
          f"(a job's wall_seconds: median {pct(walls, 50):.2f}, max {max(walls):.2f})", flush=True)

    # The killed daemon. A submitter thread submits the plan, paced, retrying each submission
    # that got no answer (with its key, as a pipeline would) until it is acknowledged.
    d = Daemon(SPRINGFITD, tmp, "killed", DAEMON_FLAGS)
    d.start()
    acked, unanswered, submit_errors = {}, [0], []
    done = threading.Event()

    def submitter():
        deadline = time.monotonic() + 300
        for key, name, seed in plan:
            while time.monotonic() < deadline:
                try:
                    c = Conn(d.port, timeout=2)
                except OSError:  # the daemon is down or restarting
                    time.sleep(0.05)
                    continue
                try:
                    resp = c.call("job.submit", params(key, name, seed), timeout=10)
                except NET_ERRORS:  # sent, but the daemon died before it answered
                    unanswered[0] += 1
                    time.sleep(0.05)
                    continue
                finally:
                    c.close()
                if "result" in resp:
                    acked.setdefault(key, set()).add(resp["result"]["job"]["job_id"])
                    break
                if resp["error"]["code"] not in (-32005, -32007):  # busy / store: retry
                    submit_errors.append(f"{key}: {resp['error']}")
                    break
                time.sleep(0.05)
            time.sleep(args.pace)
        done.set()

    thread = threading.Thread(target=submitter, daemon=True)
    thread.start()
    kills = hit_running = hit_preparing = 0
    snapshot_errors = []
    t0 = time.monotonic()
    try:
        while kills < args.kills:
            time.sleep(rng.uniform(0.1, 1.5))  # a random moment after the (re)start
            try:
                with Conn(d.port, timeout=2) as c:
                    states = [j["state"] for j in all_jobs(c)]
            except NET_ERRORS as e:
                states = None
                snapshot_errors.append(f"before kill {kills + 1}: {e}")
            if states is not None and done.is_set() and all(s in FINAL for s in states):
                break  # every job finished: nothing left to interrupt
            d.kill9()
            kills += 1
            hit_running += bool(states and "running" in states)
            hit_preparing += bool(states and "preparing" in states)
            for stream in ("stdout", "stderr"):  # keep each run's log: start() truncates them
                os.replace(os.path.join(d.dir, stream), os.path.join(d.dir, f"{stream}.{kills}"))
            d.start()
        loop_seconds = time.monotonic() - t0
        thread.join(330)
        jobs = wait_all_final(d.port, {i for ids in acked.values() for i in ids}, 600)
        print(f"kill loop: {kills} kills in {loop_seconds:.1f}s ({hit_running} with a job running, "
              f"{hit_preparing} with one preparing); {unanswered[0]} submits sent got no answer and "
              f"were retried with their key; all jobs final {time.monotonic() - t0:.1f}s after the "
              f"first start", flush=True)
        problems += submit_errors + [f"job.list failed {e}" for e in snapshot_errors]

        # The checks: acknowledged = exists, succeeded, same result and trace as the reference.
        identical = resumed = 0
        keys = {}
        for j in jobs.values():
            keys.setdefault(j["idempotency_key"], []).append(j["job_id"])
        with Conn(d.port) as c:
            for key, name, seed in plan:
                ids = acked.get(key)
                if not ids:
                    problems.append(f"{key}: never acknowledged in 300 s of retries")
                    continue
                if len(ids) > 1 or len(keys.get(key, [])) != 1:
                    problems.append(f"{key}: acknowledged as jobs {sorted(ids)}, stored as {keys.get(key)}")
                jid = min(ids)
                job = jobs.get(jid)
                if job is None:
                    problems.append(f"{key}: acknowledged job {jid} LOST (not in job.list)")
                    continue
                if job["state"] != "succeeded":
                    problems.append(f"{key}: job {jid} is {job['state']} ({job.get('error')})")
                    continue
                if key not in reference:
                    continue
                result, trace = c.result("job.result", {"job_id": jid}), full_trace(c, jid)
                ref_result, ref_trace = reference[key]
                d_result = diff(result, ref_result, "result")
                d_trace = diff(trace, ref_trace, "trace") if len(trace) == len(ref_trace) else [
                    f"trace: {len(trace)} rows, reference {len(ref_trace)}"]
                # A job resumed from a checkpoint carries on with an empty fitness cache.
                resumed += any(r["cache_hits"] != q["cache_hits"] for r, q in zip(trace, ref_trace))
                if d_result or d_trace:
                    problems.append(f"{key} (job {jid}, {name}, seed {seed}) differs: "
                                    + "; ".join((d_result + d_trace)[:6]))
                else:
                    identical += 1
        extra = set(keys) - {k for k, _, _ in plan}
        if extra:
            problems.append(f"jobs with unexpected keys: {sorted(extra, key=str)}")
        print(f"kill loop: {len(plan)} jobs, {sum(1 for k, _, _ in plan if k in acked)} acknowledged, "
              f"{identical} identical to the uninterrupted run ({resumed} of them resumed from a "
              f"checkpoint: their cache_hits differ)", flush=True)
    finally:
        done.set()
        d.stop()


# --------------------------------------------------------------------------------------------
# 2. 50-client load


def load(tmp, args, problems):
    scene = job_scene(load_scene("paper-iso-5x5"), args.load_generations)
    d = Daemon(SPRINGFITD, tmp, "load", DAEMON_FLAGS).start()
    start = threading.Barrier(args.clients)
    per_client = [dict(acked=[], states={}, get_lat=[], submit_lat=[], errors=[])
                  for _ in range(args.clients)]

    def client(i):
        out = per_client[i]
        try:
            with Conn(d.port, timeout=10) as c:
                start.wait(30)
                for j in range(args.per_client):
                    t = time.perf_counter()
                    resp = c.call("job.submit", {"scene": scene, "seed": 1 + i * 1000 + j,
                                                 "label": "load"}, timeout=30)
                    out["submit_lat"].append(time.perf_counter() - t)
                    if "result" in resp:
                        out["acked"].append(resp["result"]["job"]["job_id"])
                    else:
                        out["errors"].append(f"submit: {resp['error']}")
                pending = set(out["acked"])
                deadline = time.monotonic() + 600
                while pending and time.monotonic() < deadline:
                    for jid in sorted(pending):
                        t = time.perf_counter()
                        job = c.result("job.get", {"job_id": jid}, timeout=10)
                        out["get_lat"].append(time.perf_counter() - t)
                        if job["state"] in FINAL:
                            pending.discard(jid)
                            out["states"][jid] = job["state"]
                    time.sleep(0.1)
                if pending:
                    out["errors"].append(f"{len(pending)} jobs not finished within 600 s")
        except (NET_ERRORS + (threading.BrokenBarrierError,)) as e:
            out["errors"].append(f"{type(e).__name__}: {e}")

    t0 = time.monotonic()
    try:
        threads = [threading.Thread(target=client, args=(i,), daemon=True) for i in range(args.clients)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(700)
        wall = time.monotonic() - t0
        acked = [j for o in per_client for j in o["acked"]]
        states = {}
        for o in per_client:
            for s in o["states"].values():
                states[s] = states.get(s, 0) + 1
        with Conn(d.port) as c:
            stored = [j for j in all_jobs(c) if j["label"] == "load"]
        stored_ids = {j["job_id"] for j in stored}
        lost = [j for j in acked if j not in stored_ids]
        gets = [x for o in per_client for x in o["get_lat"]]
        subs = [x for o in per_client for x in o["submit_lat"]]
        total = args.clients * args.per_client
        print(f"load: {args.clients} clients x {args.per_client} jobs: {len(acked)}/{total} acknowledged, "
              f"finished {states}, {len(stored)} stored, {len(lost)} lost; {wall:.1f}s wall "
              f"({len(acked) / wall:.1f} jobs/s)", flush=True)
        if gets:
            print(f"load: job.get latency over {len(gets)} calls: median {pct(gets, 50) * 1e3:.2f} ms, "
                  f"p99 {pct(gets, 99) * 1e3:.2f} ms, max {max(gets) * 1e3:.2f} ms", flush=True)
        if subs:
            print(f"load: job.submit latency over {len(subs)} calls: median {pct(subs, 50) * 1e3:.2f} ms, "
                  f"p99 {pct(subs, 99) * 1e3:.2f} ms", flush=True)
        problems += [f"client {i}: {e}" for i, o in enumerate(per_client) for e in o["errors"]]
        problems += [f"acknowledged load job {j} LOST" for j in lost]
        if len(acked) != total or states.get("succeeded", 0) != total:
            problems.append(f"load: {len(acked)} acknowledged, {states} finished, expected {total} succeeded")
        if not d.alive():
            problems.append("load: the daemon died")
    finally:
        d.stop()


# --------------------------------------------------------------------------------------------


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("what", choices=("kill-loop", "load", "all"))
    ap.add_argument("--seed", type=int, default=1, help="seed of the kill moments")
    ap.add_argument("--jobs", type=int, default=100, help="kill loop: jobs (M)")
    ap.add_argument("--kills", type=int, default=50, help="kill loop: kills at most (K)")
    ap.add_argument("--generations", type=int, default=300, help="kill loop: max_generations")
    ap.add_argument("--pace", type=float, default=0.15, help="kill loop: seconds between submits")
    ap.add_argument("--clients", type=int, default=50)
    ap.add_argument("--per-client", type=int, default=10)
    ap.add_argument("--load-generations", type=int, default=20, help="load: max_generations")
    args = ap.parse_args()

    model = next((l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")), "?")
    print(f"command: {sys.executable} {' '.join(sys.argv)}")
    print(f"machine: nproc {len(os.sched_getaffinity(0))}, {model}, load average "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"daemon: {SPRINGFITD} --workers 2 {' '.join(DAEMON_FLAGS)} (tests/daemon/harness.py)", flush=True)
    tmp = tempfile.mkdtemp(prefix="springfit-outside-")
    problems = []
    t0 = time.monotonic()
    try:
        for name, fn in (("kill-loop", kill_loop), ("load", load)):
            if args.what in (name, "all"):
                before = len(problems)
                try:
                    fn(tmp, args, problems)
                except NET_ERRORS as e:
                    problems.append(f"{name}: aborted: {type(e).__name__}: {e}")
                for p in problems[before:]:
                    print(f"PROBLEM [{name}]: {p}", flush=True)
    finally:
        if problems:
            print(f"kept {tmp} (databases and daemon logs)")
        else:
            shutil.rmtree(tmp, ignore_errors=True)
    print(f"{'FAILED: ' + str(len(problems)) + ' problems' if problems else 'OK: nothing lost, nothing differed'}"
          f" ({time.monotonic() - t0:.1f}s; load average now {os.getloadavg()[0]:.2f})")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
