#!/usr/bin/env python3
"""Throughput of 1, 2 and 3 springfitd daemons on one PostgreSQL database (2 workers each),
beside one daemon on SQLite, and job.get latency under 50 clients against both stores
(bench/RESULTS.md, "Several daemons on one database").

Run from the repository root, inside a private PostgreSQL server:
    tests/server/with_postgres.sh python3 bench/multi_daemon_bench.py [BUILD_DIR]

On a 2-core machine the daemons share two cores: what this measures is the overhead of the
shared store (claims, heartbeats, fenced writes, wake-ups) and that the work spreads, not a
speed-up.
"""

import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

BUILD = sys.argv[1] if len(sys.argv) > 1 else "build"
DAEMON = os.path.join(BUILD, "server", "springfitd")
PG_DIR, PG_BIN = os.environ["SPRINGFIT_TEST_PG_DIR"], os.environ["SPRINGFIT_TEST_PG_BIN"]
TMP = tempfile.mkdtemp(prefix="springfit-mbench-")


def rpc(port, method, params):
    with socket.create_connection(("127.0.0.1", port), timeout=30) as s:
        s.sendall((json.dumps({"jsonrpc": "2.0", "id": 1, "method": method,
                               "params": params}) + "\n").encode())
        buf = b""
        while b"\n" not in buf:
            chunk = s.recv(65536)
            if not chunk:
                raise ConnectionError(method)
            buf += chunk
        return json.loads(buf.split(b"\n", 1)[0])


def database(name):
    for sql in (f"DROP DATABASE IF EXISTS {name}", f"CREATE DATABASE {name}"):
        subprocess.run([os.path.join(PG_BIN, "psql"), "-q", "-h", PG_DIR, "-U", "springfit",
                        "-d", "postgres", "-c", sql], check=True, capture_output=True)
    return f"postgresql:///{name}?host={PG_DIR}&port=5432&user=springfit"


def start(store, name):
    port_file = os.path.join(TMP, name + ".port")
    if os.path.exists(port_file):
        os.remove(port_file)
    proc = subprocess.Popen([DAEMON, "--listen", "127.0.0.1:0", "--store", store, "--port-file",
                             port_file, "--workers", "2", "--jobs", "2", "--log-level", "warn",
                             "--max-connections", "1000", "--name", name],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    for _ in range(300):
        if os.path.exists(port_file):
            return proc, int(open(port_file).read())
        time.sleep(0.05)
    raise RuntimeError("daemon did not start")


def scene(path, **search):
    s = json.load(open(path))
    s.setdefault("search", {}).update(search)
    return s


def throughput(store, daemons, jobs, workload):
    procs = [start(store, f"d{i}") for i in range(daemons)]
    ports = [p for _, p in procs]
    t0 = time.monotonic()
    ids = []
    for i in range(jobs):
        answer = rpc(ports[i % len(ports)], "job.submit",
                     {"scene": workload, "seed": i + 1, "label": "bench"})
        ids.append(answer["result"]["job"]["job_id"])
    while True:
        done = rpc(ports[0], "job.list", {"label": "bench", "state": "succeeded", "limit": 10000})
        if len(done["result"]["jobs"]) == jobs:
            break
        time.sleep(0.05)
    seconds = time.monotonic() - t0
    for proc, _ in procs:
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=30)
    return seconds


def main():
    tiny = scene("examples/paper-iso-5x5.json")                       # default: ~3 ms a job
    medium = scene("examples/paper-aniso-5x5.json", strategy="paper", max_generations=200)
    for label, workload, jobs in (("tiny (paper-iso-5x5, default)", tiny, 300),
                                  ("medium (paper-aniso-5x5, paper, 200 generations)", medium, 60)):
        print(f"{label}, {jobs} jobs:", flush=True)
        path = os.path.join(TMP, f"one-{jobs}.db")
        seconds = throughput(f"sqlite:///{path}", 1, jobs, workload)
        print(f"  sqlite, 1 daemon:     {seconds:6.2f} s, {jobs / seconds:7.1f} jobs/s", flush=True)
        for daemons in (1, 2, 3):
            store = database(f"bench_{daemons}_{jobs}")
            seconds = throughput(store, daemons, jobs, workload)
            print(f"  postgresql, {daemons} daemon{'s' if daemons > 1 else ' '}: {seconds:6.2f} s, "
                  f"{jobs / seconds:7.1f} jobs/s", flush=True)
    for name, store in (("sqlite", f"sqlite:///{os.path.join(TMP, 'get.db')}"),
                        ("postgresql", database("bench_get"))):
        proc, port = start(store, "get")
        out = subprocess.run([os.path.join(BUILD, "bench", "daemon_bench"), "--server",
                              f"127.0.0.1:{port}", "--get", "--clients", "50", "--seconds", "5"],
                             capture_output=True, text=True)
        print(f"{name}: {out.stdout.strip()}", flush=True)
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=30)


if __name__ == "__main__":
    main()
