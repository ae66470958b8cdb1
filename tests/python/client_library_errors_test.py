#!/usr/bin/env python3
"""The Python client library (python/springfit_client): its errors, and what it does not know.

Usage: client_library_errors_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts springfitd on 127.0.0.1 (a free port, SQLite in a temporary directory, a token file)
and checks: connection failures and timeouts (a closed port, a server that never answers, bad
arguments), a wrong or missing token (-32001) and the right one, and readers that ignore
members they do not know (a fake server adding some everywhere, and notifications of methods
it does not know). Python 3 standard library only (the shared part: client_library_support.py).

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import json
import socket
import sys
import threading
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
from client_library_support import (CLIENT_TIMEOUT, TOKEN, expect_rpc_error,  # noqa: E402
                                    run_groups, test_setup as shared_setup)
# (harness.py is in tests/daemon, which importing client_library_support puts on sys.path)
from harness import R  # noqa: E402

WRONG_TOKEN = "0123456789abcdefABCDEF012345678X"

sf = None   # the springfit_client module, imported from SOURCE_DIR/python in setup


def test_setup(ctx):
    """client_library_support's setup; the springfit_client module it imports is sf here."""
    global sf
    sf = shared_setup(ctx)


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


if __name__ == "__main__":
    sys.exit(run_groups(sys.argv, __doc__, [
        ("setup", test_setup, True),
        ("connection errors", test_connection_errors, False),
        ("authentication", test_auth, False),
        ("unknown members", test_unknown_members, False),
    ]))
