#!/usr/bin/env python3
"""Several springfitd daemons on one PostgreSQL database, from the outside.

Usage: multi_daemon_test.py SPRINGFITD SPRINGFIT SOURCE_DIR
Run inside tests/server/with_postgres.sh, which starts a private PostgreSQL server and sets
SPRINGFIT_TEST_PG_URL (its URL), SPRINGFIT_TEST_PG_DIR and SPRINGFIT_TEST_PG_BIN.

Checks (each on a database of its own, every wait bounded):
  load      3 daemons, 300 jobs from 30 clients, each submit retried through another daemon
            with its idempotency key: none lost, none duplicated, each run to completion once,
            the work spread over the daemons
  kill      kill -9 of the daemon running a job: another resumes it from its checkpoint once
            the lease expires, to the result and trace of an uninterrupted local run
  pause     a daemon paused (SIGSTOP) past its lease: another takes the job over, and the paused
            one, resumed, writes nothing more of it (its lease is lost); same result and trace
  restart   the database stopped under running daemons: submits are refused with -32007 (never
            acknowledged), server.info still answers; the database back, the daemons resume on
            their own, and the interrupted job ends with the uninterrupted result
  remote    job.watch and job.cancel through daemon A of a job daemon B runs
Prints PASS/FAIL per check and exits non-zero on any failure.
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

DAEMON, CLI, SRC = sys.argv[1:4]
PG_URL = os.environ.get("SPRINGFIT_TEST_PG_URL")
PG_DIR = os.environ.get("SPRINGFIT_TEST_PG_DIR")
PG_BIN = os.environ.get("SPRINGFIT_TEST_PG_BIN")
if not PG_URL:
    sys.exit("multi_daemon_test.py: run it through tests/server/with_postgres.sh "
             "(PostgreSQL from scripts/install-deps.sh)")
LEASE = 2.0
TMP = tempfile.mkdtemp(prefix="springfit-multi-")
KIDNEY = os.path.join(SRC, "examples", "kidney-2d.json")
PAPER = os.path.join(SRC, "examples", "paper-iso-5x5.json")
failures = []
daemons = []


def fail(check, what):
    failures.append((check, what))
    print(f"FAIL: [{check}] {what}", flush=True)


def psql(sql, db="postgres"):
    subprocess.run([os.path.join(PG_BIN, "psql"), "-q", "-h", PG_DIR, "-U", "springfit",
                    "-d", db, "-c", sql], check=True, capture_output=True, timeout=30)


def new_database(name):
    psql(f"DROP DATABASE IF EXISTS {name}")
    psql(f"CREATE DATABASE {name}")
    return f"postgresql:///{name}?host={PG_DIR}&port=5432&user=springfit"


def pg_ctl(*args):
    cmd = [os.path.join(PG_BIN, "pg_ctl"), "-D", os.path.join(PG_DIR, "data"), "-w", "-t", "30"]
    if os.getuid() == 0:
        cmd = ["runuser", "-u", "postgres", "--"] + cmd
    subprocess.run(cmd + list(args), check=True, capture_output=True, timeout=60)


class Daemon:
    def __init__(self, name, url):
        self.name = name
        self.log_path = os.path.join(TMP, name + ".log")
        port_file = os.path.join(TMP, name + ".port")
        if os.path.exists(port_file):
            os.remove(port_file)
        self.proc = subprocess.Popen(
            [DAEMON, "--listen", "127.0.0.1:0", "--store", url, "--port-file", port_file,
             "--workers", "2", "--jobs", "2", "--lease-seconds", str(LEASE),
             "--checkpoint-seconds", "0.2", "--name", name],
            stdout=open(self.log_path, "a"), stderr=subprocess.STDOUT)
        daemons.append(self)
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline and not os.path.exists(port_file):
            if self.proc.poll() is not None:
                raise RuntimeError(f"{name} exited: {self.log()[-500:]}")
            time.sleep(0.05)
        self.port = int(open(port_file).read())

    def log(self):
        with open(self.log_path) as f:
            return f.read()

    def kill(self, sig=signal.SIGKILL):
        self.proc.send_signal(sig)
        if sig in (signal.SIGKILL, signal.SIGTERM):
            self.proc.wait(timeout=30)

    def cli(self, *args, timeout=60):
        env = dict(os.environ, SPRINGFIT_SERVER=f"127.0.0.1:{self.port}")
        return subprocess.run([CLI] + list(args), env=env, capture_output=True, text=True,
                              timeout=timeout)


class Conn:
    """One JSON-RPC connection: requests answered in order, notifications collected."""

    def __init__(self, port):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=10)
        self.buf = b""
        self.notifications = []
        self.next_id = 1

    def close(self):
        self.sock.close()

    def read_message(self, deadline):
        while b"\n" not in self.buf:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            self.sock.settimeout(remaining)
            try:
                chunk = self.sock.recv(65536)
            except socket.timeout:
                return None
            if not chunk:
                raise ConnectionError("closed")
            self.buf += chunk
        line, self.buf = self.buf.split(b"\n", 1)
        return json.loads(line)

    def call(self, method, params=None, timeout=20):
        request_id = self.next_id
        self.next_id += 1
        message = {"jsonrpc": "2.0", "id": request_id, "method": method, "params": params or {}}
        self.sock.sendall((json.dumps(message) + "\n").encode())
        deadline = time.monotonic() + timeout
        while True:
            m = self.read_message(deadline)
            if m is None:
                raise TimeoutError(method)
            if m.get("id") == request_id:
                return m
            self.notifications.append(m)

    def wait_notification(self, predicate, timeout):
        deadline = time.monotonic() + timeout
        while True:
            for n in self.notifications:
                if predicate(n):
                    return n
            m = self.read_message(deadline)
            if m is None:
                return None
            self.notifications.append(m)


def rpc(daemon, method, params=None):
    c = Conn(daemon.port)
    try:
        return c.call(method, params)
    finally:
        c.close()


def scene(path, **search):
    s = json.load(open(path))
    s.setdefault("search", {}).update(search)
    return s


def job_of(daemon, job_id):
    """The job, or {"state": None} while the daemon answers with an error (store down)."""
    answer = rpc(daemon, "job.get", {"job_id": job_id})
    return answer.get("result") or {"state": None, "error": answer.get("error")}


def wait_state(daemon, job_id, states, timeout):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        job = job_of(daemon, job_id)
        if job["state"] in states:
            return job
        time.sleep(0.1)
    return job_of(daemon, job_id)


def wait_checkpoint(daemon, job_id, generation, timeout=30):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        c = job_of(daemon, job_id).get("checkpoint_generation")
        if c is not None and c >= generation:
            return True
        time.sleep(0.05)
    return False


def wait_log(daemon, text, timeout):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if text in daemon.log():
            return True
        time.sleep(0.1)
    return False


def same_as_local(check, daemon, job_id, scene_path, *flags):
    """The job's result and trace equal an uninterrupted local run (wall times and cache hits
    aside: a resumed job starts with an empty fitness cache)."""
    got = daemon.cli("result", str(job_id), "--json")
    trace = daemon.cli("trace", str(job_id), "--csv")
    local_trace = os.path.join(TMP, f"local-{job_id}.csv")
    local = subprocess.run([CLI, "run", scene_path, *flags, "--json", "-q", "--threads", "1",
                            "--trace", local_trace], capture_output=True, text=True, timeout=120)
    # (a local run exits 10 when its model is no answer: the short kidney runs' often is)
    # One verdict: the daemon's result exits as the local run does (0 usable, 10 unusable,
    # 11 an unmet request).
    if got.returncode != local.returncode or local.returncode not in (0, 10, 11):
        fail(check, f"job {job_id}: result exit {got.returncode} {got.stderr} / local exit "
                    f"{local.returncode} {local.stderr}")
        return
    a, b = json.loads(got.stdout), json.loads(local.stdout)
    diff = [k for k in b if k not in ("wall_seconds", "threads", "cache_hits") and a.get(k) != b[k]]
    if diff:
        fail(check, f"job {job_id}: result differs from a local run in {diff}")

    def cut(text):
        return [",".join(c for i, c in enumerate(line.split(",")) if i not in (1, 3))
                for line in text.strip().splitlines()]
    if cut(trace.stdout) != cut(open(local_trace).read()):
        fail(check, f"job {job_id}: trace differs from an uninterrupted local run")


def stop_all():
    for d in daemons:
        if d.proc.poll() is None:
            try:
                d.proc.send_signal(signal.SIGCONT)
                d.kill(signal.SIGKILL)
            except Exception:
                pass
    daemons.clear()


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
    if not wait_log(a, "lease lost", 10):
        fail("pause", "the resumed daemon A did not find its lease lost")
    if f"job {job_id} succeeded" in a.log():
        fail("pause", "the paused daemon ran the job to completion too")
    same_as_local("pause", b, job_id, KIDNEY, *flags)
    if rpc(a, "server.info").get("result", {}).get("daemon") != "pause-a":
        fail("pause", "daemon A does not answer after its pause")
    stop_all()


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


def main():
    checks = [check_load, check_kill, check_pause, check_restart, check_stall, check_remote]
    only = os.environ.get("MULTI_ONLY")  # one check by name, when debugging
    ran = 0
    for check in checks:
        name = check.__name__[len("check_"):]
        if only and name != only:
            continue
        before = len(failures)
        ran += 1
        t0 = time.monotonic()
        try:
            check()
        except Exception as e:  # noqa: BLE001 - a crash of a check is its failure
            fail(name, f"{type(e).__name__}: {e}")
        finally:
            stop_all()
        status = "PASS" if len(failures) == before else "FAIL"
        print(f"{status}: {name} ({time.monotonic() - t0:.1f} s)", flush=True)
    if failures:
        for name in sorted({f[0] for f in failures}):
            for p in os.listdir(TMP):
                if p.startswith(name) and p.endswith(".log"):
                    print(f"--- {p}\n" + open(os.path.join(TMP, p)).read()[-2000:])
    failed = len({f[0] for f in failures})
    print(f"{ran - failed} passed, {failed} failed")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
