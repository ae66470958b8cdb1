#!/usr/bin/env python3
"""The Python client library (python/springfit_client) against a real springfitd.

Usage: client_library_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts springfitd on 127.0.0.1 (a free port, SQLite in a temporary directory, a token file)
and checks: `pip install` of python/ offline into a plain venv (no setuptools, no wheel) and the
installed copy talking to the daemon; connection failures and timeouts; a
wrong or missing token (-32001); readers that ignore members they do not know (a fake server
adding some everywhere); submit, watch with a progress callback (notifications and polling),
result with springs and a verdict, list and trace over several pages, export to .vtu,
cancelling a finished job (-32006) and a running one, delete, unknown job ids (-32002),
idempotency keys, search options, submit_mesh through `springfit import`; and runs README.md's
"Python client" example verbatim. Python 3 standard library only.

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "daemon"))
from harness import STOP_TIMEOUT, Abort, Daemon, R, require, run_suite, short  # noqa: E402

CLIENT_TIMEOUT = 10.0     # the Client's timeout: to connect and for each answer
JOB_TIMEOUT = 60.0        # for a small job to finish (watch's timeout)
PIP_TIMEOUT = 120.0       # for venv and pip install
EXAMPLE_TIMEOUT = 60.0    # for README.md's example
GROUP_TIMEOUT = 180       # for one group: a library that hangs fails the group, not the run
TOKEN = "0123456789abcdefABCDEF0123456789"
WRONG_TOKEN = "0123456789abcdefABCDEF012345678X"
DEBIAN_PYTHON = "/usr/bin/python3"   # Debian's, with python3-venv from install-deps.sh
VERDICTS = ("usable", "unmet_request", "unusable")

sf = None   # the springfit_client module, imported from SOURCE_DIR/python in setup


# --------------------------------------------------------------------------------------------
# The context


class Context:
    def __init__(self, springfitd, springfit, source):
        self.springfitd = springfitd
        self.springfit = springfit
        self.source = source
        self.tmp = tempfile.mkdtemp(prefix="springfit-pyclient-test-")
        self.daemons = []
        self.main = None
        self.token_file = os.path.join(self.tmp, "token")
        self.nonce = f"{os.getpid()}-{time.time_ns()}"
        self.iso_path = os.path.join(self.tmp, "paper-iso-5x5.json")
        self.kidney_path = os.path.join(self.tmp, "kidney-2d.json")
        self.long_jobs = []   # cancelled at cleanup if still running
        self.finished_job = None   # (job id, Job) of the round trip

    def server(self):
        return f"127.0.0.1:{self.main.port}"

    def client(self, **kwargs):
        kwargs.setdefault("token_file", self.token_file)
        kwargs.setdefault("timeout", CLIENT_TIMEOUT)
        kwargs.setdefault("springfit", self.springfit)
        return sf.Client(self.server(), **kwargs)

    def cleanup(self):
        R.current = "cleanup"
        if self.main is not None and self.main.alive() and self.long_jobs:
            try:
                with self.client() as c:
                    for job_id in self.long_jobs:
                        try:
                            c.cancel(job_id)
                        except sf.RpcError:
                            pass
            except (OSError, sf.SpringfitError):
                pass
        for d in self.daemons:
            if d.alive():
                R.expect(d.stop(), f"daemon {d.name} did not exit within {STOP_TIMEOUT}s of SIGTERM")
            else:
                d.close_files()
        shutil.rmtree(self.tmp, ignore_errors=True)


def clean_env(**extra):
    env = {k: v for k, v in os.environ.items() if not k.startswith("SPRINGFIT_")}
    env.update(extra)
    return env


def expect_rpc_error(what, code, fn, *args, **kwargs):
    """Calls fn, which must raise RpcError with `code`; returns the error (or None)."""
    try:
        value = fn(*args, **kwargs)
    except sf.RpcError as e:
        R.expect(e.code == code, f"{what}: RpcError code {e.code}, expected {code}: {e}")
        R.expect(isinstance(e.message, str) and e.message, f"{what}: RpcError without a message")
        R.expect(isinstance(e.data, dict), f"{what}: RpcError.data is {type(e.data).__name__}")
        return e
    except Exception as e:  # reported, not raised: the group goes on
        R.fail(f"{what}: expected RpcError {code}, got {type(e).__name__}: {e}")
        return None
    R.fail(f"{what}: expected RpcError {code}, got the answer {short(value)}")
    return None


def wait_for(c, job_id, states, timeout):
    deadline = time.monotonic() + timeout
    while True:
        job = c.status(job_id)
        if job.state in states or time.monotonic() > deadline:
            return job
        time.sleep(0.05)


# --------------------------------------------------------------------------------------------
# A fake server: answers with members no springfitd sends (yet), and notifications of
# methods it does not know


FUTURE = {"added_in_a_later_version": {"nested": [1, 2, 3]}, "another_new_member": "x"}


def with_future(obj):
    out = dict(obj)
    out.update(FUTURE)
    return out


def fake_job(job_id, state):
    finished = state in ("succeeded", "failed", "cancelled")
    row = with_future({"generation": 3, "wall_seconds": 0.5, "evaluations": 80, "cache_hits": 1,
                       "best_cost": 0.25, "best_normalized_error": 0.0625, "mean_cost": 2.0,
                       "missing": 1, "extra": 2})
    outcome = with_future({"verdict": "unmet_request", "headline": "usable: 7 springs, E 0.25",
                           "reason": "", "unmet": ["spring budget not met: ..."], "springs": 7,
                           "unseen_springs": 0, "rms_error": 0.25, "baseline_rms_error": None,
                           "held_out": None})
    return with_future({"job_id": job_id, "label": "fake", "priority": 0, "seed": 1,
                        "idempotency_key": None, "state": state, "error": None, "scene": "s",
                        "genes": 9, "strategy": "paper", "max_generations": 10,
                        "created_at": 1.0, "started_at": 2.0, "finished_at": 3.0 if finished else None,
                        "progress": row, "checkpoint_generation": None, "exact": False,
                        "outcome": outcome if finished else None})


class FakeServer:
    """JSON-RPC on 127.0.0.1 answering a few methods with extra members everywhere; mode
    "silent" accepts connections and never answers."""

    def __init__(self, mode="future"):
        self.mode = mode
        self.listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.listener.bind(("127.0.0.1", 0))
        self.listener.listen(8)
        self.listener.settimeout(0.1)
        self.port = self.listener.getsockname()[1]
        self.stop_event = threading.Event()
        self.conns = []
        self.requests = []
        self.thread = threading.Thread(target=self._accept, daemon=True)
        self.thread.start()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop_event.set()
        self.thread.join(2)
        self.listener.close()
        for c in self.conns:
            c.close()

    def _accept(self):
        while not self.stop_event.is_set():
            try:
                conn, _ = self.listener.accept()
            except socket.timeout:
                continue
            except OSError:
                return
            self.conns.append(conn)
            if self.mode != "silent":
                threading.Thread(target=self._serve, args=(conn,), daemon=True).start()

    def _serve(self, conn):
        buf = b""
        conn.settimeout(10)
        try:
            while True:
                chunk = conn.recv(65536)
                if not chunk:
                    return
                buf += chunk
                while b"\n" in buf:
                    line, buf = buf.split(b"\n", 1)
                    request = json.loads(line)
                    self.requests.append(request)
                    for message in self._answer(request):
                        conn.sendall(json.dumps(message).encode() + b"\n")
        except OSError:
            return

    def _answer(self, request):
        method, params, rid = request["method"], request.get("params") or {}, request["id"]
        notice = {"jsonrpc": "2.0", "method": "server.future_notice", "params": FUTURE}

        def answer(result):
            return with_future({"jsonrpc": "2.0", "id": rid, "result": result})
        if method == "server.info":
            return [notice, answer(with_future({
                "name": "springfitd", "version": "9.9", "protocol": 1, "auth_required": False,
                "workers": 2, "limits": with_future({"max_page": 10000})}))]
        if method == "job.get":
            return [notice, answer(fake_job(params["job_id"], "running"))]
        if method == "job.watch":
            job_id = params["job_id"]
            progress = with_future(dict(fake_job(job_id, "running")["progress"], job_id=job_id,
                                        max_generations=10))
            other = dict(progress, job_id=job_id + 1)
            return [answer(fake_job(job_id, "running")),
                    {"jsonrpc": "2.0", "method": "job.progress", "params": other},
                    {"jsonrpc": "2.0", "method": "job.progress", "params": progress},
                    notice,
                    {"jsonrpc": "2.0", "method": "job.finished", "params": fake_job(job_id, "succeeded")}]
        if method == "job.list":
            cursor = params.get("cursor")
            first = cursor is None
            jobs = [fake_job(1, "succeeded"), fake_job(2, "queued")] if first else [fake_job(3, "running")]
            return [answer(with_future({"jobs": jobs, "next_cursor": 2 if first else None}))]
        if method == "job.result":
            return [answer(with_future({"job_id": params["job_id"], "state": "succeeded",
                                        "springs": [[0, 1], [1, 2]], "rms_error": 0.25,
                                        "outcome": fake_job(1, "succeeded")["outcome"]}))]
        if method == "job.trace":
            after = params.get("after", -1)
            rows = [dict(fake_job(1, "running")["progress"], generation=g) for g in (after + 1, after + 2)]
            return [answer(with_future({"job_id": params["job_id"], "rows": rows,
                                        "next_after": rows[-1]["generation"] if after < 0 else None}))]
        return [{"jsonrpc": "2.0", "id": rid, "error": with_future(
            {"code": -32601, "message": f"method not found: {method}",
             "data": with_future({"method": method})})}]


# --------------------------------------------------------------------------------------------
# The tests


def test_setup(ctx):
    global sf
    for name in [k for k in os.environ if k.startswith("SPRINGFIT_")]:
        del os.environ[name]   # the Client's defaults: none from the caller's environment
    sys.path.insert(0, os.path.join(ctx.source, "python"))
    import springfit_client
    sf = springfit_client
    require(os.path.dirname(os.path.abspath(sf.__file__)) ==
            os.path.join(os.path.abspath(ctx.source), "python", "springfit_client"),
            f"springfit_client imported from {sf.__file__}, not from {ctx.source}/python")
    with open(ctx.token_file, "w") as f:
        f.write(TOKEN + "\n")
    os.chmod(ctx.token_file, 0o600)
    for name, path in (("paper-iso-5x5", ctx.iso_path), ("kidney-2d", ctx.kidney_path)):
        p = subprocess.run([ctx.springfit, "example", name, "-o", path], capture_output=True,
                           timeout=30, env=clean_env())
        require(p.returncode == 0, f"springfit example {name}: exit {p.returncode}: {p.stderr!r}")
    d = Daemon(ctx.springfitd, ctx.tmp, "main", ["--token-file", ctx.token_file])
    ctx.daemons.append(d)
    ctx.main = d.start()


def test_package(ctx):
    """pip install of python/ into a plain venv, offline (--no-index), with and without build
    isolation, in a venv from which setuptools and wheel are removed (Python 3.12's venvs have
    neither; an install that needed them failed there with "invalid command 'bdist_wheel'"):
    the project's own build backend needs nothing but pip. With Debian's python3 (python3-venv
    from install-deps.sh) and, where it is another one, the python3 running this test. The
    installed copy, run by the venv's python, talks to the daemon."""
    pythons = [DEBIAN_PYTHON] if os.access(DEBIAN_PYTHON, os.X_OK) else []
    if not pythons or os.path.realpath(sys.executable) != os.path.realpath(DEBIAN_PYTHON):
        pythons.append(sys.executable)
    env = clean_env(PIP_ROOT_USER_ACTION="ignore", PIP_DISABLE_PIP_VERSION_CHECK="1",
                    PYTHONDONTWRITEBYTECODE="1")
    src = os.path.join(ctx.source, "python")
    for n, python in enumerate(pythons):
        venv = os.path.join(ctx.tmp, f"venv{n}")
        p = subprocess.run([python, "-m", "venv", venv], capture_output=True, timeout=PIP_TIMEOUT)
        require(p.returncode == 0, f"{python} -m venv: exit {p.returncode} (run "
                                   f"scripts/install-deps.sh: python3-venv): {short(p.stderr.decode(), 600)}")
        vpy = os.path.join(venv, "bin", "python")
        pip = [vpy, "-m", "pip"]
        subprocess.run(pip + ["uninstall", "-y", "--quiet", "setuptools", "wheel"],
                       capture_output=True, timeout=PIP_TIMEOUT, env=env)
        probe = subprocess.run([vpy, "-c", "import setuptools"], capture_output=True, timeout=30)
        R.expect(probe.returncode != 0, f"{venv}: setuptools is still there: the venv is not plain")
        for isolation in ([], ["--no-build-isolation"]):
            subprocess.run(pip + ["uninstall", "-y", "--quiet", "springfit-client"],
                           capture_output=True, timeout=PIP_TIMEOUT, env=env)
            p = subprocess.run(pip + ["install", "--no-index", "--quiet", *isolation, src],
                               capture_output=True, timeout=PIP_TIMEOUT, env=env)
            R.expect(p.returncode == 0, f"{python}: pip install --no-index {' '.join(isolation)} "
                                        f"./python in a plain venv: exit {p.returncode}: "
                                        f"{short(p.stderr.decode(), 1500)}")
        # The installed copy (not the source tree), by the name pip knows it, against the daemon.
        code = ("import sys, importlib.metadata as m, springfit_client as s\n"
                "assert s.__file__.startswith(sys.prefix), s.__file__\n"
                "files = {f.name for f in m.files('springfit-client')}\n"
                "assert {'__init__.py', 'client.py', 'py.typed'} <= files, files\n"
                "with s.Client(sys.argv[1], token_file=sys.argv[2], timeout=10) as c:\n"
                "    print(m.version('springfit-client'), c.info().name, c.info().auth_required)\n")
        p = subprocess.run([vpy, "-c", code, ctx.server(), ctx.token_file],
                           capture_output=True, timeout=60, env=env, cwd=ctx.tmp)
        R.expect(p.returncode == 0 and p.stdout.decode().split() == ["1.0.0", "springfitd", "True"],
                 f"{python}: the venv's package against the daemon: exit {p.returncode}, stdout "
                 f"{p.stdout.decode()!r}, stderr {short(p.stderr.decode(), 800)}")


def test_connection_errors(ctx):
    # Nothing listens: a ConnectionError subclass saying where.
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    free_port = s.getsockname()[1]
    s.close()
    c = sf.Client(f"127.0.0.1:{free_port}", timeout=5)
    try:
        c.info()
        R.fail("info() with nothing listening: no error")
    except sf.ServerConnectionError as e:
        R.expect(isinstance(e, ConnectionError), f"{type(e).__name__} is not a ConnectionError")
        R.expect(not isinstance(e, sf.ServerTimeout), f"a refused connection is a timeout: {e}")
        R.expect(f"127.0.0.1:{free_port}" in str(e), f"the error does not name the address: {e}")
    except Exception as e:
        R.fail(f"info() with nothing listening: {type(e).__name__}: {e}")
    # A server that never answers: ServerTimeout after `timeout` seconds, not later.
    with FakeServer("silent") as fake:
        c = sf.Client(f"127.0.0.1:{fake.port}", timeout=0.5)
        t0 = time.monotonic()
        try:
            c.info()
            R.fail("info() against a silent server: no error")
        except sf.ServerTimeout as e:
            wall = time.monotonic() - t0
            R.expect(isinstance(e, ConnectionError) and isinstance(e, TimeoutError),
                     f"ServerTimeout is not both a ConnectionError and a TimeoutError: {type(e).__mro__}")
            R.expect(0.4 <= wall < 3.0, f"the timeout of 0.5 s took {wall:.2f} s")
            R.expect("did not answer within 0.5 s" in str(e), f"the timeout's message: {e}")
        except Exception as e:
            R.fail(f"info() against a silent server: {type(e).__name__}: {e}")
    # Bad arguments are refused before any connection.
    for what, kwargs in (("a port that is no number", {"server": "127.0.0.1:x"}),
                         ("a port beyond 65535", {"server": "127.0.0.1:65536"}),
                         ("no port", {"server": "localhost"}),
                         ("token and token_file", {"server": "127.0.0.1:1", "token": "a", "token_file": ctx.token_file}),
                         ("an empty token", {"server": "127.0.0.1:1", "token": "  "})):
        try:
            sf.Client(**kwargs)
            R.fail(f"Client with {what}: accepted")
        except ValueError:
            pass


def test_auth(ctx):
    # A wrong token: session.auth answers -32001, raised by the first call.
    with sf.Client(ctx.server(), token=WRONG_TOKEN, timeout=CLIENT_TIMEOUT) as c:
        e = expect_rpc_error("a wrong token", -32001, c.info)
        R.expect(e is None or e.method == "session.auth",
                 f"the wrong token's error comes from {e and e.method}, expected session.auth")
    # No token: server.info answers (auth_required), job methods -32001.
    with sf.Client(ctx.server(), timeout=CLIENT_TIMEOUT) as c:
        info = c.info()
        R.expect(info.name == "springfitd" and info.auth_required is True and info.protocol == 1,
                 f"server.info without a token: {info}")
        expect_rpc_error("job.list without a token", sf.UNAUTHORIZED, c.list)
        expect_rpc_error("job.submit without a token", -32001, c.submit, ctx.iso_path)
    # The right token, as a string and as a file.
    with sf.Client(ctx.server(), token=TOKEN, timeout=CLIENT_TIMEOUT) as c:
        R.expect(isinstance(c.list(limit=1), list), "job.list with the token as a string")
    with ctx.client() as c:
        R.expect(isinstance(c.list(limit=1), list), "job.list with the token file")


def test_unknown_members(ctx):
    """Readers ignore members they do not know (proto/RPC.md), and notifications of methods
    they do not know; the fake server adds some to every object and message."""
    with FakeServer() as fake, sf.Client(f"127.0.0.1:{fake.port}", timeout=5) as c:
        info = c.info()
        R.expect(info.version == "9.9" and info.workers == 2 and info.queued is None,
                 f"server.info with unknown members: {info}")
        R.expect(info["added_in_a_later_version"] == FUTURE["added_in_a_later_version"],
                 "an unknown member is not kept in raw")
        job = c.status(7)
        R.expect(job.job_id == 7 and job.state == "running" and job.progress.generation == 3 and
                 job.progress.missing == 1 and abs(job.rms_error - 0.25) < 1e-12,
                 f"job.get with unknown members: {job}")
        seen = []
        final = c.watch(7, on_progress=seen.append, timeout=5)
        R.expect(final.state == "succeeded" and final.verdict == "unmet_request" and
                 final.outcome.unmet == ["spring budget not met: ..."] and final.outcome.usable,
                 f"job.finished with unknown members: {final}")
        # A doubtful verdict is a usable model whose doubts the record carries.
        doubtful = sf.Outcome.from_json({"verdict": sf.DOUBTFUL, "doubts": ["a soft mode: ..."]})
        R.expect(doubtful.usable and doubtful.doubts == ["a soft mode: ..."],
                 f"a doubtful outcome: {doubtful}")
        R.expect([(p.job_id, p.generation, p.max_generations, p.final) for p in seen] == [(7, 3, 10, False)],
                 f"watch reported {seen}, expected job 7's one progress (not job 8's, and not the "
                 "final row again)")
        jobs = c.list()
        R.expect([j.job_id for j in jobs] == [1, 2, 3], f"job.list over two pages: {[j.job_id for j in jobs]}")
        R.expect([j.verdict for j in jobs] == ["unmet_request", None, None], f"verdicts: {[j.verdict for j in jobs]}")
        R.expect([j.job_id for j in c.list(limit=2)] == [1, 2], "job.list with limit 2")
        result = c.result(7)
        R.expect(result.springs == [[0, 1], [1, 2]] and result.verdict == "unmet_request",
                 f"job.result with unknown members: {result}")
        rows = c.trace(7)
        R.expect([r.generation for r in rows] == [0, 1, 2, 3], f"job.trace over two pages: {rows}")
        e = expect_rpc_error("an unknown method", sf.METHOD_NOT_FOUND, c.call, "job.future")
        R.expect(e is None or e.data.get("method") == "job.future", f"the error's data: {e and e.data}")
        methods = [r["method"] for r in fake.requests]
        R.expect(methods.count("job.list") == 3, f"job.list requests: {methods}")
        unknown_params = [r for r in fake.requests if r["method"] in ("job.get", "job.watch")
                          and set(r.get("params", {})) != {"job_id"}]
        R.expect(not unknown_params, f"requests with more than job_id: {unknown_params}")


def test_round_trip(ctx):
    label = f"round-trip-{ctx.nonce}"
    with ctx.client() as c:
        # A job of a couple of seconds, so that job.progress notifications come while it runs.
        job_id = c.submit(ctx.kidney_path, label=label, seed=5, priority=3, strategy="paper",
                          generations=40)
        R.expect(isinstance(job_id, int), f"submit returned {job_id!r}, not a job id")
        seen = []
        job = c.watch(job_id, on_progress=seen.append, timeout=JOB_TIMEOUT)
        R.expect(job.job_id == job_id and job.state == "succeeded", f"the watched job: {job}")
        R.expect(job.verdict in VERDICTS and job.outcome.verdict == job.verdict and
                 isinstance(job.outcome.rms_error, float), f"the finished job's verdict: {job.outcome}")
        R.expect(job.label == label and job.seed == 5 and job.priority == 3 and
                 job.strategy == "paper" and job.max_generations == 40,
                 f"the job's label, seed, priority, strategy, generation limit: {job}")
        live = [p for p in seen if not p.final]
        R.expect(len(seen) >= 1, "watch: on_progress was never called")
        R.expect(len(live) >= 1, f"watch: no job.progress notification reached on_progress: {seen}")
        R.expect(all(p.job_id == job_id and p.max_generations == 40 for p in seen),
                 f"progress of another job or without its limit: {seen}")
        gens = [p.generation for p in seen]
        R.expect(gens == sorted(gens) and len(set(gens)) == len(gens), f"progress generations: {gens}")
        R.expect(seen[-1].generation == 40 and seen[-1].final == (len(seen) > len(live)),
                 f"the last progress reported: {seen[-1]}")
        ctx.finished_job = (job_id, job)
        # Watching a finished job, by notifications and by polling: its last row, once.
        for poll in (None, 0.05):
            again = []
            job2 = c.watch(job_id, on_progress=again.append, poll_interval=poll, timeout=JOB_TIMEOUT)
            R.expect(job2.state == "succeeded" and job2.verdict == job.verdict,
                     f"watch (poll_interval {poll}) of the finished job: {job2}")
            R.expect([(p.generation, p.final, p.job_id) for p in again] == [(40, True, job_id)],
                     f"watch (poll_interval {poll}) of the finished job reported {again}")

        result = c.result(job_id)
        R.expect(result.job_id == job_id and result.state == "succeeded", f"result: {result}")
        R.expect(isinstance(result.springs, list) and len(result.springs) > 0 and
                 all(isinstance(s, list) and len(s) == 2 for s in result.springs),
                 f"result.springs: {short(result.springs)}")
        R.expect(result.verdict == job.verdict and result.outcome.springs == len(result.springs),
                 f"result.outcome {result.outcome} against the job's verdict {job.verdict}")
        R.expect(result.generations == 40 and result.ran == "paper" and result.seed == 5,
                 f"result: {result}")

        rows = c.trace(job_id)
        R.expect([r.generation for r in rows] == list(range(41)),
                 f"trace generations: {[r.generation for r in rows]}")
        R.expect(all(isinstance(r.best_normalized_error, float) for r in rows), "trace rows' errors")

        listed = [j for j in c.list() if j.job_id == job_id]
        R.expect(len(listed) == 1 and listed[0].verdict == job.verdict, f"list() finds the job: {listed}")
        by_label = c.list(label=label)
        R.expect([j.job_id for j in by_label] == [job_id], f"list(label=...): {by_label}")
        R.expect(job_id in [j.job_id for j in c.list(state="succeeded")], "list(state='succeeded')")
        R.expect(c.list(label=label, state="running") == [], "list(label, state='running') is not empty")

        vtu = os.path.join(ctx.tmp, "model.vtu")
        R.expect(c.export(job_id, vtu) == vtu, "export returns the path")
        with open(vtu, "rb") as f:
            head = f.read(4096)
        R.expect(head.startswith(b"<?xml") and b'<VTKFile type="UnstructuredGrid"' in head,
                 f"the exported .vtu: {short(head)}")
        # The command's options, by the same names: a SOFA scene for a release, with masses.
        scn = os.path.join(ctx.tmp, "model.scn")
        c.export(job_id, scn, node_mass=2.5, sofa_version="v24.06", dead_fraction=1e-4)
        with open(scn, encoding="utf-8") as f:
            text = f.read()
        R.expect("SOFA v24.06" in text and 'vertexMass="2.5"' in text,
                 f"export's options reach the scene: {short(text)}")
        try:
            c.export(job_id, scn, sofa_version="v1.0")
            R.fail("export with an unknown SOFA release: no error")
        except sf.CliError as e:
            R.expect(e.returncode == 2 and "v1.0" in e.stderr, f"an unknown release: {e}")
        try:
            c.export(987654, os.path.join(ctx.tmp, "none.vtu"))
            R.fail("export of an unknown job: no error")
        except sf.CliError as e:
            R.expect(e.returncode == 4 and "no such job" in e.stderr, f"export of an unknown job: {e}")

        # Cancelling a finished job: -32006 with its state.
        e = expect_rpc_error("cancel of a finished job", sf.WRONG_STATE, c.cancel, job_id)
        R.expect(e is None or e.data.get("state") == "succeeded", f"its data: {e and e.data}")
        R.expect(c.status(job_id).state == "succeeded", "the finished job changed after cancel")

        # An unknown id: -32002 with the id, from every method that names a job.
        unknown = 987654
        for name, fn in (("status", c.status), ("result", c.result), ("trace", c.trace),
                         ("cancel", c.cancel), ("delete", c.delete), ("watch", c.watch)):
            e = expect_rpc_error(f"{name} of an unknown job", sf.NO_SUCH_JOB, fn, unknown)
            R.expect(e is None or e.data.get("job_id") == unknown, f"{name}: the error's data: {e and e.data}")
        R.expect(c.status(job_id).job_id == job_id, "the connection after the errors")


def test_paging(ctx):
    """list() and trace() follow next_cursor / next_after: the pages made small."""
    label = f"paging-{ctx.nonce}"
    client_module = sys.modules["springfit_client.client"]
    saved = client_module._LIST_PAGE, client_module._TRACE_PAGE
    try:
        with ctx.client() as c:
            ids = [c.submit(ctx.iso_path, label=label) for _ in range(5)]
            for job_id in ids:
                c.watch(job_id, timeout=JOB_TIMEOUT)
            client_module._LIST_PAGE, client_module._TRACE_PAGE = 2, 7
            R.expect([j.job_id for j in c.list(label=label)] == ids, f"list over pages of 2: {ids}")
            R.expect([j.job_id for j in c.list(label=label, order="newest")] == ids[::-1],
                     "list newest first over pages of 2")
            R.expect([j.job_id for j in c.list(label=label, limit=3)] == ids[:3], "list with limit 3")
            if ctx.finished_job is not None:
                rows = c.trace(ctx.finished_job[0])
                R.expect([r.generation for r in rows] == list(range(41)),
                         f"trace over pages of 7: {[r.generation for r in rows]}")
    finally:
        client_module._LIST_PAGE, client_module._TRACE_PAGE = saved


def test_submit_options(ctx):
    key = f"key-{ctx.nonce}"
    with ctx.client() as c:
        with open(ctx.iso_path) as f:
            scene = json.load(f)
        before = json.dumps(scene, sort_keys=True)
        first = c.submit_job(scene, idempotency_key=key, strategy="paper", generations=7, stall=3,
                             search={"population": 12})
        R.expect(first.created is True and first.job.idempotency_key == key, f"first submit: {first}")
        again = c.submit_job(scene, idempotency_key=key, strategy="paper", generations=7, stall=3,
                             search={"population": 12})
        R.expect(again.created is False and again.job.job_id == first.job.job_id,
                 f"a second submit with the key: {again}")
        R.expect(json.dumps(scene, sort_keys=True) == before, "submit changed the caller's scene")
        stored = c.scene(first.job.job_id)
        want = {"strategy": "paper", "max_generations": 7, "stall_generations": 3, "population": 12}
        got = {k: stored.get("search", {}).get(k) for k in want}
        R.expect(got == want, f"the stored scene's search: {got}, expected {want}")
        c.watch(first.job.job_id, timeout=JOB_TIMEOUT)
        # The probe fit's options, as springfit submit's --max-spread and --load-size write them.
        tuned = c.submit(ctx.kidney_path, label=f"tuned-{ctx.nonce}", strategy="continuous",
                         max_spread=1000, load_size=0.5)
        search = c.scene(tuned).get("search", {})
        R.expect(search.get("max_spread") == 1000 and search.get("load_size") == 0.5,
                 f"the stored scene's search: {search}")
        c.watch(tuned, timeout=JOB_TIMEOUT)
        try:
            c.submit(scene, generation=5)
            R.fail("submit with an unknown option: accepted")
        except TypeError:
            pass
        # An invalid scene: -32003 with the field's path.
        bad = json.loads(before)
        bad["reference"]["springs"][0] = [0, 999]
        e = expect_rpc_error("an invalid scene", sf.INVALID_SCENE, c.submit, bad)
        R.expect(e is None or e.data.get("path", "").startswith("reference.springs[0]"),
                 f"the invalid scene's path: {e and e.data}")


def test_notices_and_phases(ctx):
    """A submission's notices, and the phases a watch reports between rows (job.phase)."""
    with open(os.path.join(ctx.source, "examples", "fem-kidney-2d.json")) as f:
        scene = json.load(f)
    scene["reference"]["material"]["poisson"] = 0.495
    scene["name"] = f"locking kidney {ctx.nonce}"
    with ctx.client() as c:
        submitted = c.submit_job(scene)
        R.expect(submitted.created and any("0.495" in n for n in submitted.notices or []),
                 f"the submission's notices: {submitted.notices}")
        phases = []
        job = c.watch(submitted.job.job_id, on_phase=phases.append, timeout=JOB_TIMEOUT)
        R.expect(job.finished, f"the job: {job}")
        known = {"direct", "genetic", "regularization", "fit", "path", "refit", "held_out",
                 "probes", "probe_fit", "probe_path", "probe_refine", "probe_lift",
                 "nonlinear_fit", "certificate", "nonlinear"}
        R.expect(phases and all(isinstance(p, sf.Phase) and p.job_id == job.job_id and
                                p.phase in known and p.wall_seconds >= 0 for p in phases),
                 f"on_phase: {phases}")


def test_cancel_delete(ctx):
    with ctx.client() as c:
        job_id = c.submit(ctx.kidney_path, label=f"long-{ctx.nonce}", strategy="paper",
                          generations=100000)
        ctx.long_jobs.append(job_id)
        job = wait_for(c, job_id, ("running",), 20)
        require(job.state == "running", f"the long job does not run: {job}")
        e = expect_rpc_error("delete of a running job", sf.WRONG_STATE, c.delete, job_id)
        R.expect(e is None or e.data.get("state") == "running", f"its data: {e and e.data}")
        # A watch that times out leaves the job running and the client usable.
        t0 = time.monotonic()
        try:
            c.watch(job_id, timeout=1.0)
            R.fail("watch(timeout=1) of a long job returned")
        except sf.WatchTimeout as e:
            R.expect(e.job is not None and e.job.job_id == job_id, f"WatchTimeout.job: {e.job}")
        R.expect(time.monotonic() - t0 < 5, f"watch(timeout=1) took {time.monotonic() - t0:.1f} s")
        R.expect(c.status(job_id).state == "running", "the job after a watch's timeout")
        state = c.cancel(job_id)
        R.expect(state == "cancelling", f"cancel of a running job: {state!r}, expected 'cancelling'")
        seen = []
        job = c.watch(job_id, on_progress=seen.append, poll_interval=0.1, timeout=JOB_TIMEOUT)
        R.expect(job.state == "cancelled" and job.finished, f"the cancelled job: {job}")
        R.expect(len(seen) >= 1 and seen[-1].job_id == job_id, f"polling watch's progress: {seen}")
        result = c.result(job_id)   # the best so far of a job cancelled while running
        R.expect(result.state == "cancelled" and result.stop == "cancelled", f"its result: {result}")
        c.delete(job_id)
        expect_rpc_error("status of a deleted job", sf.NO_SUCH_JOB, c.status, job_id)


def write_square_mesh(path, n=4, size=1.0):
    """An n x n-node square as Gmsh MSH 2.2 (ASCII): 2 (n-1)^2 triangles, physical curves
    "left" and "right", physical surface "body"."""
    h = size / (n - 1)

    def tag(x, y):
        return y * n + x + 1
    nodes = [f"{tag(x, y)} {x * h:g} {y * h:g} 0" for y in range(n) for x in range(n)]
    elements = []
    for y in range(n - 1):
        elements.append(("1 2 1 1", (tag(0, y), tag(0, y + 1))))
        elements.append(("1 2 2 2", (tag(n - 1, y), tag(n - 1, y + 1))))
        for x in range(n - 1):
            a, b, c, d = tag(x, y), tag(x + 1, y), tag(x + 1, y + 1), tag(x, y + 1)
            elements += [("2 2 3 3", (a, b, c)), ("2 2 3 3", (a, c, d))]
    lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", "3",
             '1 1 "left"', '1 2 "right"', '2 3 "body"', "$EndPhysicalNames",
             "$Nodes", str(len(nodes))] + nodes + ["$EndNodes", "$Elements", str(len(elements))]
    lines += [f"{i + 1} {kind} {' '.join(map(str, ns))}" for i, (kind, ns) in enumerate(elements)]
    lines.append("$EndElements")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def test_submit_mesh(ctx):
    mesh = os.path.join(ctx.tmp, "square.msh")
    loads = os.path.join(ctx.tmp, "square-loads.json")
    write_square_mesh(mesh)
    with open(loads, "w") as f:
        json.dump({"reference": {"material": {"model": "linear", "young": 1, "poisson": 0.3},
                                 "plane": "stress", "thickness": 1},
                   "load_cases": [{"name": "stretch", "fixed": "left",
                                   "tractions": [{"on": "right", "total": [0.01, 0]}]},
                                  {"name": "shear", "fixed": "left",
                                   "tractions": [{"on": "right", "total": [0, 0.002]}]}]}, f)
    with ctx.client() as c:
        job_id = c.submit_mesh(mesh, loads, label=f"mesh-{ctx.nonce}")
        job = c.watch(job_id, timeout=JOB_TIMEOUT)
        R.expect(job.scene == "square" and job.state == "succeeded" and job.strategy == "continuous",
                 f"the mesh's job: {job}")
        R.expect(job.verdict in VERDICTS and job.outcome.baseline_rms_error is not None,
                 f"the mesh job's outcome: {job.outcome}")
        stored = c.scene(job_id)
        R.expect(len(stored.get("nodes", [])) == 16 and stored.get("reference", {}).get("type") == "fem",
                 f"the stored scene of the mesh: {short(stored)}")
        # A mesh alone (no loads) is imported, and refused for its missing load cases.
        e = expect_rpc_error("submit of a mesh without loads", sf.INVALID_SCENE, c.submit, mesh)
        R.expect(e is None or e.data.get("path") == "load_cases", f"its data: {e and e.data}")
        try:
            c.submit_mesh(os.path.join(ctx.tmp, "no-such.msh"), loads)
            R.fail("submit_mesh of a missing file: no error")
        except sf.CliError as e:
            R.expect(e.returncode == 2 and "no-such.msh" in e.stderr, f"submit_mesh of a missing file: {e}")


def readme_example(source):
    """The code block between README.md's python-client markers."""
    with open(os.path.join(source, "README.md"), encoding="utf-8") as f:
        text = f.read()
    m = re.search(r"<!-- python-client -->\s*```python\n(.*?)```\s*<!-- /python-client -->", text, re.S)
    require(m, "README.md has no ```python block between <!-- python-client --> markers")
    return m.group(1)


def test_readme_example(ctx):
    code = readme_example(ctx.source)
    work = os.path.join(ctx.tmp, "readme")
    os.makedirs(os.path.join(work, "examples"))
    shutil.copy(os.path.join(ctx.source, "examples", "paper-iso-5x5.json"), os.path.join(work, "examples"))
    env = clean_env(SPRINGFIT_SERVER=ctx.server(), SPRINGFIT_TOKEN=TOKEN,
                    PYTHONPATH=os.path.join(ctx.source, "python"), PYTHONDONTWRITEBYTECODE="1",
                    PATH=os.path.dirname(ctx.springfit) + os.pathsep + os.environ.get("PATH", ""))
    p = subprocess.run([sys.executable, "-c", code], cwd=work, capture_output=True,
                       timeout=EXAMPLE_TIMEOUT, env=env)
    out, err = p.stdout.decode(), p.stderr.decode()
    R.expect(p.returncode == 0, f"README's example: exit {p.returncode}: {short(err, 1500)}")
    m = re.search(r"^job (\d+) succeeded, verdict usable: E 0\b", out, re.M)
    R.expect(m, f"README's example: no 'job N succeeded, verdict usable: E 0' line: {out!r}")
    R.expect(re.search(r"^job \d+: generation 0/1000, E ", out, re.M),
             f"README's example printed no progress: {out!r}")
    R.expect("72 springs, recovered exactly: True" in out, f"README's example: {out!r}")
    R.expect("cancel: " in out and "(-32006)" in out, f"README's example's cancel: {out!r}")
    vtu = os.path.join(work, "model.vtu")
    R.expect(os.path.isfile(vtu) and os.path.getsize(vtu) > 0, "README's example wrote no model.vtu")
    if m:
        with ctx.client() as c:
            job = c.status(int(m.group(1)))
            R.expect(job.label == "readme" and job.seed == 7, f"README's job: {job}")


def bounded(fn):
    """fn(ctx), aborted by SIGALRM after GROUP_TIMEOUT seconds (a blocking read included)."""
    def run(ctx):
        def expired(signum, frame):
            raise Abort(f"the group did not finish within {GROUP_TIMEOUT} s")
        previous = signal.signal(signal.SIGALRM, expired)
        signal.alarm(GROUP_TIMEOUT)
        try:
            fn(ctx)
        finally:
            signal.alarm(0)
            signal.signal(signal.SIGALRM, previous)
    return run


def main(argv):
    groups = [
        ("setup", test_setup, True),
        ("pip install in a plain venv", test_package, False),
        ("connection errors", test_connection_errors, False),
        ("authentication", test_auth, False),
        ("unknown members", test_unknown_members, False),
        ("submit, watch, result, list, trace, export", test_round_trip, False),
        ("paging", test_paging, False),
        ("submit options", test_submit_options, False),
        ("notices and phases", test_notices_and_phases, False),
        ("cancel and delete", test_cancel_delete, False),
        ("submit_mesh", test_submit_mesh, False),
        ("README example", test_readme_example, False),
    ]
    groups = [(name, bounded(fn), essential) for name, fn, essential in groups]
    return run_suite(argv, __doc__.strip().split("\n\n")[1], Context, groups,
                     lambda daemon: daemon.log_text())


if __name__ == "__main__":
    sys.exit(main(sys.argv))
