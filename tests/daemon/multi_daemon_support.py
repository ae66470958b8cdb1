"""The shared part of the tests of several springfitd daemons on one PostgreSQL database
(multi_daemon_jobs_test.py, multi_daemon_failover_test.py and multi_daemon_database_test.py).

Imported by a test script run as `SCRIPT SPRINGFITD SPRINGFIT SOURCE_DIR` inside
tests/server/with_postgres.sh, which starts a private PostgreSQL server and sets
SPRINGFIT_TEST_PG_URL (its URL), SPRINGFIT_TEST_PG_DIR and SPRINGFIT_TEST_PG_BIN.

Failures (fail), a database of each check's own (new_database), the server stopped and started
(pg_ctl), a daemon with its log (Daemon), a JSON-RPC connection collecting notifications
(Conn), job polling, a job's result and trace compared with an uninterrupted local run
(same_as_local), and run_checks, which runs a script's checks and prints PASS/FAIL for each.
"""

import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time

DAEMON, CLI, SRC = sys.argv[1:4]
PG_URL = os.environ.get("SPRINGFIT_TEST_PG_URL")
PG_DIR = os.environ.get("SPRINGFIT_TEST_PG_DIR")
PG_BIN = os.environ.get("SPRINGFIT_TEST_PG_BIN")
if not PG_URL:
    sys.exit(f"{os.path.basename(sys.argv[0])}: run it through tests/server/with_postgres.sh "
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
    """Whether `text` (or, given a tuple, any of its strings) appears in the daemon's log
    within `timeout` seconds."""
    texts = text if isinstance(text, tuple) else (text,)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        log = daemon.log()
        if any(t in log for t in texts):
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


def run_checks(checks):
    """Runs the checks (functions named check_NAME) in order, each followed by stop_all, prints
    PASS/FAIL for each, the failed checks' daemon logs and a total; exits 1 on any failure."""
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
