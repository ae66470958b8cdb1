"""Shared scaffolding of the daemon's end-to-end tests (protocol_*_test.py, client_*_test.py).

Reporting (Report, the shared instance R, Abort, require, short), a JSON-RPC connection with a
line reader (Conn), job polling (wait_state) and a springfitd started on 127.0.0.1 with a free
port in a directory of its own (Daemon). Python 3 standard library only.
"""

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import traceback

IO_TIMEOUT = 5.0          # seconds any single socket read/connect may block
START_TIMEOUT = 10.0      # for the port file to appear
STOP_TIMEOUT = 15.0       # for the daemon to exit after SIGTERM (--shutdown-seconds is 10)


# --------------------------------------------------------------------------------------------
# Reporting


class Report:
    def __init__(self):
        self.failures = []
        self.current = "?"
        self.lock = threading.Lock()

    def fail(self, what):
        with self.lock:
            self.failures.append((self.current, what))
        print(f"FAIL: [{self.current}] {what}", flush=True)

    def expect(self, cond, what):
        """A soft check: records a failure and returns cond."""
        if not cond:
            self.fail(what)
        return bool(cond)


R = Report()


class Abort(Exception):
    """A check whose failure makes the rest of its group meaningless."""


def require(cond, what):
    if not cond:
        raise Abort(what)


def short(value, n=300):
    text = value if isinstance(value, str) else repr(value)
    return text if len(text) <= n else text[:n] + "..."


# --------------------------------------------------------------------------------------------
# A connection with a line reader


def is_compact(line):
    """True when a JSON text has no whitespace outside strings."""
    in_string = escaped = False
    for ch in line:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in " \t\r\n":
            return False
    return True


class Conn:
    # When true, read() also checks (softly, through R) that each response line is compact
    # JSON. A test sets Conn.check_compact for all its connections, or passes check_compact.
    check_compact = False

    def __init__(self, port, timeout=IO_TIMEOUT, check_compact=None):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=timeout)
        self.buf = b""
        self.eof = False
        self.next_id = 1000
        if check_compact is not None:
            self.check_compact = check_compact

    def close(self):
        try:
            self.sock.close()
        except OSError:
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def send(self, data):
        self.sock.settimeout(IO_TIMEOUT)
        self.sock.sendall(data)

    def _fill(self, deadline):
        """Reads once into the buffer; False on timeout, sets eof on close/reset."""
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return False
        self.sock.settimeout(remaining)
        try:
            chunk = self.sock.recv(65536)
        except socket.timeout:
            return False
        except (ConnectionResetError, ConnectionAbortedError):
            chunk = b""
        if not chunk:
            self.eof = True
            return False
        self.buf += chunk
        return True

    def read_raw_line(self, timeout=IO_TIMEOUT):
        """One line without its newline, or None (timeout or closed)."""
        deadline = time.monotonic() + timeout
        while b"\n" not in self.buf:
            if self.eof or not self._fill(deadline):
                return None
        line, self.buf = self.buf.split(b"\n", 1)
        return line

    def read(self, timeout=IO_TIMEOUT, what="a response"):
        """One response line, checked to be exactly one JSON value (and compact JSON when
        check_compact is set); returns it parsed."""
        line = self.read_raw_line(timeout)
        if line is None:
            raise Abort(f"no {what} within {timeout}s (connection {'closed' if self.eof else 'open'}, "
                        f"pending bytes {short(self.buf)})")
        try:
            text = line.decode("utf-8")
            value = json.loads(text)
        except (UnicodeDecodeError, ValueError) as e:
            raise Abort(f"response line is not one JSON value ({e}): {short(line)}")
        if self.check_compact:
            R.expect(is_compact(text), f"response line is not compact JSON: {short(text)}")
        return value

    def silent(self, wait):
        """True when nothing arrives within `wait` seconds."""
        if self.buf:
            return False
        self._fill(time.monotonic() + wait)
        return not self.buf

    def wait_closed(self, timeout=IO_TIMEOUT):
        """True when the peer closes the connection within the timeout (extra data is skipped)."""
        deadline = time.monotonic() + timeout
        while not self.eof:
            self.buf = b""
            if not self._fill(deadline) and not self.eof:
                return False
        return True

    def request(self, method, params=None, id_=None):
        """Sends one request line; returns its id."""
        if id_ is None:
            self.next_id += 1
            id_ = self.next_id
        msg = {"jsonrpc": "2.0", "id": id_, "method": method}
        if params is not None:
            msg["params"] = params
        self.send(json.dumps(msg).encode() + b"\n")
        return id_

    def read_answer(self, timeout=IO_TIMEOUT, what="a response"):
        """Like read, skipping the job.preparing notifications a slow job.submit sends before
        its answer (proto/RPC.md)."""
        while True:
            resp = self.read(timeout, what)
            if not (isinstance(resp, dict) and resp.get("method") == "job.preparing"):
                return resp

    def call(self, method, params=None, timeout=IO_TIMEOUT):
        """Sends a request and reads its response (which must carry its id)."""
        id_ = self.request(method, params)
        resp = self.read_answer(timeout, what=f"answer to {method}")
        require(isinstance(resp, dict) and resp.get("id") == id_,
                f"{method}: expected the answer with id {id_}, got {short(resp)}")
        return resp

    def call_text(self, method, params_text, timeout=IO_TIMEOUT):
        """Like call, with the params written by hand (number literals kept as written)."""
        self.next_id += 1
        id_ = self.next_id
        text = '{"jsonrpc":"2.0","id":%d,"method":"%s","params":%s}\n' % (id_, method, params_text)
        self.send(text.encode())
        resp = self.read_answer(timeout, what=f"answer to {method}")
        require(isinstance(resp, dict) and resp.get("id") == id_,
                f"{method}: expected the answer with id {id_}, got {short(resp)}")
        return resp

    def result(self, method, params=None, timeout=IO_TIMEOUT):
        resp = self.call(method, params, timeout)
        require("result" in resp, f"{method} {short(params)}: expected a result, got {short(resp)}")
        return resp["result"]


def error_data(err):
    data = err.get("data")
    return data if isinstance(data, dict) else {}


def wait_state(conn, job_id, states, timeout, interval=0.05):
    """Polls job.get every `interval` seconds until the job is in one of `states` or the timeout
    passes; the last job."""
    deadline = time.monotonic() + timeout
    while True:
        job = conn.result("job.get", {"job_id": job_id})
        if job["state"] in states or time.monotonic() > deadline:
            return job
        time.sleep(interval)


def grid_scene(n, name):
    """An n x n grid MSS (edges and both diagonals of every cell), fixed on the left, pulled on
    the right: n^2 nodes, a scene the daemon takes seconds to prepare at n = 120."""
    def idx(x, y):
        return y * n + x
    springs = []
    for y in range(n):
        for x in range(n):
            if x + 1 < n:
                springs.append([idx(x, y), idx(x + 1, y)])
            if y + 1 < n:
                springs.append([idx(x, y), idx(x, y + 1)])
            if x + 1 < n and y + 1 < n:
                springs += [[idx(x, y), idx(x + 1, y + 1)], [idx(x + 1, y), idx(x, y + 1)]]
    return {"name": name, "nodes": [[x, y] for y in range(n) for x in range(n)],
            "reference": {"type": "mss", "springs": springs},
            "load_cases": [{"fixed": [idx(0, y) for y in range(n)],
                            "forces": [{"nodes": [idx(n - 1, y) for y in range(n)], "force": [0.01, 0.002]}]}]}


# --------------------------------------------------------------------------------------------
# The daemon


class Daemon:
    """springfitd on 127.0.0.1:0 with its database, port file, stdout and stderr in
    ROOT/NAME; `extra` arguments are appended to the command line."""

    def __init__(self, binary, root, name, extra=(), setup=None):
        """setup: called in the child before springfitd starts (limits, signal dispositions)."""
        self.setup = setup
        self.binary = binary
        self.dir = os.path.join(root, name)
        os.makedirs(self.dir)
        self.name = name
        self.extra = list(extra)
        self.proc = None
        self.port = None
        self.stderr = None
        self.stdout = None
        self.db = os.path.join(self.dir, "test.db")

    def start(self):
        port_file = os.path.join(self.dir, "port")
        if os.path.exists(port_file):
            os.remove(port_file)  # a restart: the port is the new process's
        self.stderr = open(os.path.join(self.dir, "stderr"), "wb")
        self.stdout = open(os.path.join(self.dir, "stdout"), "wb")
        self.proc = subprocess.Popen(
            [self.binary, "--listen", "127.0.0.1:0", "--db", self.db,
             "--port-file", port_file, "--workers", "2", "--log-level", "warn"] + self.extra,
            stdin=subprocess.DEVNULL, stdout=self.stdout, stderr=self.stderr,
            preexec_fn=self._child_setup)
        deadline = time.monotonic() + START_TIMEOUT
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise Abort(f"daemon {self.name} exited at start with {self.proc.returncode}: "
                            f"{short(self.log_text(), 500)}")
            try:
                with open(port_file) as f:
                    text = f.read().strip()
                if text:
                    self.port = int(text)
                    return self
            except (OSError, ValueError):
                pass
            time.sleep(0.02)
        raise Abort(f"daemon {self.name}: no port file within {START_TIMEOUT}s")

    def _child_setup(self):
        os.umask(0o022)  # a usual umask: the database's mode is the daemon's doing
        if self.setup is not None:
            self.setup()

    def alive(self):
        return self.proc is not None and self.proc.poll() is None

    def output_text(self, stream):
        try:
            with open(os.path.join(self.dir, stream), "rb") as f:
                return f.read().decode("utf-8", "replace")
        except OSError:
            return ""

    def stderr_text(self):
        return self.output_text("stderr")

    def log_text(self):
        """The daemon's log: spdlog's default logger writes to stdout; errors at start also go
        to stderr. Both, stdout first."""
        return self.output_text("stdout") + self.output_text("stderr")

    def close_files(self):
        for f in (self.stdout, self.stderr):
            if f is not None:
                f.close()

    def kill9(self):
        """SIGKILL, as a crash: nothing of the daemon runs after it."""
        if self.alive():
            self.proc.kill()
            self.proc.wait(5)
        self.close_files()

    def stop(self):
        """SIGTERM, bounded wait; True when it exited in time."""
        if self.proc is None:
            return True
        exited = True
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                exited = False
                self.proc.kill()
                self.proc.wait(5)
        self.close_files()
        return exited


# --------------------------------------------------------------------------------------------
# Running a suite of groups


def run_suite(argv, usage, make_context, groups, main_output):
    """Runs a test script's groups in order and returns its exit code.

    argv is SPRINGFITD SPRINGFIT SOURCE_DIR; make_context(springfitd, springfit, source) builds
    the script's context, whose `main` is its shared daemon (or None) and whose cleanup() stops
    what it started. groups are (name, function(ctx), essential): a failed essential group
    stops the run, since the rest depend on it. main_output(daemon) is the text quoted when the
    shared daemon died during the run.
    """
    if len(argv) != 4:
        print(usage, file=sys.stderr)
        return 2
    springfitd, springfit, source = (os.path.abspath(a) for a in argv[1:])
    for path in (springfitd, springfit):
        if not os.access(path, os.X_OK):
            print(f"FAIL: not an executable: {path}", file=sys.stderr)
            return 2
    started = time.monotonic()
    ctx = make_context(springfitd, springfit, source)
    try:
        for name, fn, essential in groups:
            R.current = name
            before = len(R.failures)
            t0 = time.monotonic()
            try:
                fn(ctx)
            except Abort as e:
                R.fail(f"aborted: {e}")
            except Exception as e:
                R.fail(f"unexpected {type(e).__name__}: {e}\n{traceback.format_exc()}")
            R.current = name
            failed = len(R.failures) - before
            print(f"{'PASS' if not failed else 'FAIL'}: {name} ({time.monotonic() - t0:.1f}s"
                  f"{'' if not failed else f', {failed} failed checks'})", flush=True)
            if failed and essential:
                print(f"FAIL: stopping: the {name} group is needed by the rest", flush=True)
                break
        if ctx.main is not None:
            R.current = "end"
            R.expect(ctx.main.alive(), f"the main daemon died: {short(main_output(ctx.main), 500)}")
    finally:
        ctx.cleanup()
    total = time.monotonic() - started
    if R.failures:
        print(f"FAILED: {len(R.failures)} checks failed ({total:.1f}s)")
        return 1
    print(f"OK: all checks passed ({total:.1f}s)")
    return 0
