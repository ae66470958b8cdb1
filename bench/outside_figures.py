#!/usr/bin/env python3
"""Re-measures the "outside figures" of the external robustness review of springfitd
(build/server/springfitd; nothing is built). usage: outside_figures.py kill-loop|load|all

kill-loop: M small jobs are submitted (with idempotency keys, paced so that kills hit submissions
too) while springfitd is killed with SIGKILL at random (seeded) moments and restarted on the same
database, K times or until every job has finished. Every acknowledged job must then be stored
once, have succeeded, and have the result and trace of the same scene+seed on a daemon that is
never killed (proto/RPC.md, "Durability": equal but for wall times and cache_hits).
load: 50 client threads each submit 10 small jobs and poll job.get until they finish; none may be
lost. The job.get latency is the clients' view (50 Python threads share one interpreter lock).
The hostile-corpus figure is tests/daemon/protocol_corpus_test.py's. Exit status 1 when anything was
lost or differed; the temporary directory (databases, daemon logs) is then kept.
"""
import argparse
import collections
import hashlib
import json
import math
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
SCENES = ("paper-iso-5x5", "paper-aniso-5x5")  # paper, 300 generations: 0.5-1 s a job alone
# Jobs of ~1 s never reach the default 10 s checkpoint, so every kill would restart them from
# scratch; a short interval makes kills land after checkpoints and exercises the resume path.
DAEMON_FLAGS = ["--checkpoint-seconds", "0.1"]
# Not reproducible by design (proto/RUN.md, proto/RPC.md): wall times, the fitness cache's
# hits, threads, the job's id in its database; and any *_at time stamp.
IGNORED = {"wall_seconds", "cache_hits", "seconds", "model_seconds", "threads", "job_id"}
NET_ERRORS = (OSError, Abort)  # refused, reset, timed out: the daemon is down or restarting


def binary_id():
    """springfitd's mtime and hash, to tie the figures to a build (others may rebuild it)."""
    with open(SPRINGFITD, "rb") as f:
        digest = hashlib.sha256(f.read()).hexdigest()[:12]
    return f"{time.strftime('%Y-%m-%d %H:%M:%S', time.localtime(os.path.getmtime(SPRINGFITD)))} sha256 {digest}"


STARTED_BUILDS = set()  # mtimes of the springfitd files the daemons were started from


def start(d):
    d.start()
    STARTED_BUILDS.add(os.path.getmtime(SPRINGFITD))
    return d


def job_scene(name, generations):
    with open(os.path.join(ROOT, "examples", name + ".json")) as f:
        scene = json.load(f)
    scene["search"] = dict(scene.get("search", {}), strategy="paper", max_generations=generations)
    return scene


def pct(values, p):
    """Nearest-rank percentile of a non-empty list."""
    return sorted(values)[max(0, math.ceil(p / 100 * len(values)) - 1)]


def diff(a, b, path=""):
    """Paths where two JSON values differ, IGNORED keys left out (floats compared exactly)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return [d for k in sorted(set(a) | set(b)) if k not in IGNORED and not k.endswith("_at")
                for d in diff(a.get(k, "<absent>"), b.get(k, "<absent>"), f"{path}.{k}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in diff(x, y, f"{path}[{i}]")]
    return [] if a == b and type(a) is type(b) else [f"{path}: {str(a)[:80]} != {str(b)[:80]}"]


def all_jobs(c):
    jobs, cursor = [], None
    while True:
        page = c.result("job.list", {"limit": 10000, **({"cursor": cursor} if cursor else {})})
        jobs, cursor = jobs + page["jobs"], page["next_cursor"]
        if cursor is None:
            return jobs


def full_trace(c, job_id):
    rows, after = [], -1
    while after is not None:  # pages of 100 rows, so that the paging is checked too
        page = c.result("job.trace", {"job_id": job_id, "after": after, "limit": 100})
        rows, after = rows + page["rows"], page["next_after"]
    return rows


def wait_all_final(port, ids, timeout):
    """Polls job.list until every job of `ids` is final or absent (lost: the caller reports
    that); the jobs by id."""
    deadline = time.monotonic() + timeout
    with Conn(port) as c:
        while True:
            jobs = {j["job_id"]: j for j in all_jobs(c)}
            if all(jobs[i]["state"] in FINAL for i in ids if i in jobs) or time.monotonic() > deadline:
                return jobs
            time.sleep(0.25)


# --------------------------------------------------------------------------------------------
# 1. kill -9 loop


def run_reference(tmp, plan, params, problems):
    """The plan on a daemon that is never killed: {key: (result, trace)}."""
    t0, reference = time.monotonic(), {}
    ref = start(Daemon(SPRINGFITD, tmp, "reference", DAEMON_FLAGS))
    try:
        with Conn(ref.port) as c:
            ids = {k: c.result("job.submit", params(k, n, s), timeout=30)["job"]["job_id"] for k, n, s in plan}
        jobs = wait_all_final(ref.port, ids.values(), 600)
        with Conn(ref.port) as c:
            for key, jid in ids.items():
                if jobs.get(jid, {}).get("state") == "succeeded":
                    reference[key] = (c.result("job.result", {"job_id": jid}), full_trace(c, jid))
                else:
                    problems.append(f"reference job {key} (id {jid}): {jobs.get(jid)}")
    finally:
        ref.stop()
    walls = [r["wall_seconds"] for r, _ in reference.values()] or [0]
    print(f"reference run: {len(reference)}/{len(plan)} jobs succeeded in {time.monotonic() - t0:.1f}s "
          f"(a job's wall_seconds: median {pct(walls, 50):.2f}, max {max(walls):.2f})", flush=True)
    return reference


def submit_all(d, plan, params, pace, acked, counts, problems, done):
    """Submits the plan to the daemon being killed, each submission retried (with its key, as a
    pipeline would) until it is answered; acked[key] = the job ids it was acknowledged with."""
    deadline = time.monotonic() + 300
    for key, name, seed in plan:
        while time.monotonic() < deadline:
            connected = False
            try:
                with Conn(d.port, timeout=2) as c:
                    connected = True
                    resp = c.call("job.submit", params(key, name, seed), timeout=10)
            except NET_ERRORS:  # refused (down, restarting), or it died before it answered
                counts["unanswered"] += connected
                time.sleep(0.05)
                continue
            if "result" in resp:
                acked.setdefault(key, set()).add(resp["result"]["job"]["job_id"])
                break
            if resp["error"]["code"] not in (-32005, -32007):  # busy, store unavailable: retry
                problems.append(f"{key}: submit answered {resp['error']}")
                break
            time.sleep(0.05)
        time.sleep(pace)
    done.set()


def kill_loop(tmp, args, problems):
    rng = random.Random(args.seed)
    scenes = {n: job_scene(n, args.generations) for n in SCENES}
    plan = [(f"kill-{i}", SCENES[i % 2], 1000 + i) for i in range(args.jobs)]  # key, scene, seed

    def params(key, name, seed):
        return {"scene": scenes[name], "seed": seed, "idempotency_key": key, "label": "kill-loop"}

    reference = run_reference(tmp, plan, params, problems)
    d = start(Daemon(SPRINGFITD, tmp, "killed", DAEMON_FLAGS))
    acked, counts, done = {}, collections.Counter(), threading.Event()
    thread = threading.Thread(target=submit_all, daemon=True,
                              args=(d, plan, params, args.pace, acked, counts, problems, done))
    t0 = time.monotonic()
    thread.start()
    try:
        while counts["kills"] < args.kills:
            time.sleep(rng.uniform(0.1, 1.5))  # a random moment after the (re)start
            try:
                with Conn(d.port, timeout=2) as c:
                    states = {j["state"] for j in all_jobs(c)}
            except NET_ERRORS as e:
                states = set()
                problems.append(f"job.list before kill {counts['kills'] + 1}: {e}")
            if done.is_set() and states and states <= set(FINAL):
                break  # every job finished: nothing left to interrupt
            d.kill9()
            counts["kills"] += 1
            counts["running"] += "running" in states
            counts["preparing"] += "preparing" in states
            for stream in ("stdout", "stderr"):  # keep each run's log: start() truncates them
                os.replace(os.path.join(d.dir, stream), os.path.join(d.dir, f"{stream}.{counts['kills']}"))
            start(d)
        loop_seconds = time.monotonic() - t0
        thread.join(330)
        jobs = wait_all_final(d.port, {i for ids in acked.values() for i in ids}, 600)
        print(f"kill loop: {counts['kills']} kills in {loop_seconds:.1f}s ({counts['running']} with a job "
              f"running, {counts['preparing']} with one preparing); {counts['unanswered']} submits got no "
              f"answer and were retried with their key; all jobs final {time.monotonic() - t0:.1f}s after "
              f"the first start", flush=True)
        with Conn(d.port) as c:
            check_killed(c, plan, acked, jobs, reference, problems)
    finally:
        done.set()
        d.stop()


def check_killed(c, plan, acked, jobs, reference, problems):
    """Every acknowledged job: stored once, succeeded, result and trace as the reference's."""
    by_key, identical, resumed = collections.defaultdict(list), 0, 0
    for j in jobs.values():
        by_key[j["idempotency_key"]].append(j["job_id"])
    for key, name, seed in plan:
        ids = acked.get(key)
        if not ids:
            problems.append(f"{key}: never acknowledged in 300 s of retries")
            continue
        if len(ids) > 1 or len(by_key[key]) != 1:
            problems.append(f"{key}: acknowledged as jobs {sorted(ids)}, stored as {by_key[key]}")
        jid = min(ids)
        job = jobs.get(jid)
        if job is None or job["state"] != "succeeded":
            problems.append(f"{key}: acknowledged job {jid} is " + (
                "LOST (not in job.list)" if job is None else f"{job['state']} ({job.get('error')})"))
            continue
        if key not in reference:
            continue
        result, trace = c.result("job.result", {"job_id": jid}), full_trace(c, jid)
        ref_result, ref_trace = reference[key]
        found = diff(result, ref_result, "result") + (diff(trace, ref_trace, "trace") if len(trace) == len(
            ref_trace) else [f"trace: {len(trace)} rows, reference {len(ref_trace)}"])
        # A job resumed from a checkpoint goes on with an empty fitness cache (cache_hits is
        # otherwise reproducible): this counts the resumes the kills caused.
        resumed += any(r["cache_hits"] != q["cache_hits"] for r, q in zip(trace, ref_trace))
        if found:
            problems.append(f"{key} (job {jid}, {name}, seed {seed}) differs: " + "; ".join(found[:6]))
        else:
            identical += 1
    print(f"kill loop: {len(plan)} jobs, {sum(k in acked for k, _, _ in plan)} acknowledged, {identical} "
          f"identical to the uninterrupted run ({resumed} of them resumed from a checkpoint: their "
          f"cache_hits differ)", flush=True)


# --------------------------------------------------------------------------------------------
# 2. 50-client load


def load_client(port, i, args, scene, barrier, out):
    """One client: its jobs submitted one after the other, then job.get on each unfinished one
    every 0.1 s until all are final."""
    try:
        with Conn(port, timeout=10) as c:
            barrier.wait(30)
            for j in range(args.per_client):
                t = time.perf_counter()
                resp = c.call("job.submit", {"scene": scene, "seed": 1 + i * 1000 + j, "label": "load"}, timeout=30)
                out["submit"].append(time.perf_counter() - t)
                if "result" in resp:
                    out["acked"].append(resp["result"]["job"]["job_id"])
                else:
                    out["errors"].append(f"submit: {resp['error']}")
            pending, deadline = set(out["acked"]), time.monotonic() + 600
            while pending and time.monotonic() < deadline:
                for jid in sorted(pending):
                    t = time.perf_counter()
                    job = c.result("job.get", {"job_id": jid}, timeout=10)
                    out["get"].append(time.perf_counter() - t)
                    if job["state"] in FINAL:
                        pending.discard(jid)
                        out["states"].append(job["state"])
                time.sleep(0.1)
            if pending:
                out["errors"].append(f"{len(pending)} jobs not finished within 600 s")
    except NET_ERRORS + (threading.BrokenBarrierError,) as e:
        out["errors"].append(f"{type(e).__name__}: {e}")


def load(tmp, args, problems):
    scene = job_scene("paper-iso-5x5", args.load_generations)  # ~0.1 s a job
    # 50 clients + 1 listing connection: the default --max-connections (256) suffices.
    d = start(Daemon(SPRINGFITD, tmp, "load", DAEMON_FLAGS))
    barrier = threading.Barrier(args.clients)
    outs = [collections.defaultdict(list) for _ in range(args.clients)]
    threads = [threading.Thread(target=load_client, args=(d.port, i, args, scene, barrier, outs[i]),
                                daemon=True) for i in range(args.clients)]
    t0 = time.monotonic()
    try:
        for t in threads:
            t.start()
        for t in threads:
            t.join(max(1, t0 + 700 - time.monotonic()))
        wall = time.monotonic() - t0
        merged = {k: [x for o in outs for x in o[k]] for k in ("acked", "states", "get", "submit")}
        states, total = collections.Counter(merged["states"]), args.clients * args.per_client
        with Conn(d.port) as c:
            stored = {j["job_id"] for j in all_jobs(c) if j["label"] == "load"}
        lost = [j for j in merged["acked"] if j not in stored]
        print(f"load: {args.clients} clients x {args.per_client} jobs: {len(merged['acked'])}/{total} "
              f"acknowledged, finished {dict(states)}, {len(stored)} stored, {len(lost)} lost; "
              f"{wall:.1f}s wall ({len(merged['acked']) / wall:.1f} jobs/s)", flush=True)
        for what, lat in (("get", merged["get"]), ("submit", merged["submit"])):
            if lat:
                print(f"load: job.{what} latency over {len(lat)} calls: median {pct(lat, 50) * 1e3:.2f} ms, "
                      f"p99 {pct(lat, 99) * 1e3:.2f} ms, max {max(lat) * 1e3:.2f} ms", flush=True)
        problems += [f"client {i}: {e}" for i, o in enumerate(outs) for e in o["errors"]]
        problems += [f"acknowledged load job {j} LOST" for j in lost]
        if len(merged["acked"]) != total or states["succeeded"] != total:
            problems.append(f"{len(merged['acked'])} acknowledged, {dict(states)}, expected {total} succeeded")
        if not d.alive():
            problems.append("the daemon died")
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

    with open("/proc/cpuinfo") as f:
        model = next((l.split(":", 1)[1].strip() for l in f if l.startswith("model name")), "?")
    print(f"command: {sys.executable} {' '.join(sys.argv)}")
    print(f"machine: nproc {len(os.sched_getaffinity(0))}, {model}, load average "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    build = binary_id()
    print(f"springfitd build: {build}")
    print(f"daemon: {SPRINGFITD} --listen 127.0.0.1:0 --db DIR/test.db --port-file DIR/port "
          f"--workers 2 --log-level warn {' '.join(DAEMON_FLAGS)}", flush=True)
    tmp, problems, t0 = tempfile.mkdtemp(prefix="springfit-outside-"), [], time.monotonic()
    try:
        for name, fn in (("kill-loop", kill_loop), ("load", load)):
            if args.what in (name, "all"):
                before = len(problems)
                try:
                    fn(tmp, args, problems)
                except NET_ERRORS as e:
                    problems.append(f"aborted: {type(e).__name__}: {e}")
                for p in problems[before:]:
                    print(f"PROBLEM [{name}]: {p}", flush=True)
    finally:
        if problems:
            print(f"kept {tmp} (databases and daemon logs)")
        else:
            shutil.rmtree(tmp, ignore_errors=True)
    if len(STARTED_BUILDS) > 1:
        print(f"WARNING: springfitd was rebuilt during the run: daemons were started from {len(STARTED_BUILDS)} "
              f"builds (now {binary_id()}); the figures mix them")
    print(f"{f'FAILED: {len(problems)} problems' if problems else 'OK: nothing lost, nothing differed'} "
          f"({time.monotonic() - t0:.1f}s; load average now {os.getloadavg()[0]:.2f})")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
