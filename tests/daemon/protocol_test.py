#!/usr/bin/env python3
"""Outside-in test of springfitd's JSON-RPC/TCP protocol (proto/RPC.md).

Usage: protocol_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts daemons on 127.0.0.1 with a free port in temporary directories and checks, against
the documented behaviour: framing, the malformed-input corpus (error codes, the connection
surviving), over-size messages, the daemon and an earlier job surviving the corpus,
authentication, the connection limit, 500 concurrent submissions with idempotency keys and
the exit codes of the springfit client. Python 3 standard library only.

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree for harness.py
from harness import (IO_TIMEOUT, STOP_TIMEOUT, Abort, Conn, Daemon, R, error_data, require, run_suite,
                     short, wait_state)

# IO_TIMEOUT (5 s), START_TIMEOUT (10 s) and STOP_TIMEOUT (15 s) are harness.py's.
CLI_TIMEOUT = 20.0        # for one springfit invocation
LOAD_THREADS = 50
LOAD_JOBS = 500
LOAD_DEADLINE = 40.0      # for all load jobs to be submitted and finished

TOKEN = "0123456789abcdefABCDEF0123456789"        # 32 characters
WRONG_TOKEN = "0123456789abcdefABCDEF012345678X"  # same length, last character differs

DOCUMENTED_CODES = {-32700, -32600, -32601, -32602, -32603, -32001, -32002, -32003, -32004,
                    -32005, -32006, -32007}


# Every response line must be compact JSON (checked by Conn.read).
Conn.check_compact = True


def expect_error(resp, code, what, id_=None, check_id=True):
    """Checks that resp is an error response with `code`; returns its error object or {}."""
    ok = R.expect(isinstance(resp, dict) and isinstance(resp.get("error"), dict),
                  f"{what}: expected error {code}, got {short(resp)}")
    if not ok:
        return {}
    err = resp["error"]
    R.expect(resp.get("jsonrpc") == "2.0", f"{what}: response lacks jsonrpc 2.0: {short(resp)}")
    R.expect(err.get("code") == code, f"{what}: expected code {code}, got {err.get('code')}: {short(resp)}")
    R.expect(isinstance(err.get("message"), str) and err["message"],
             f"{what}: error without a message: {short(resp)}")
    if check_id:
        R.expect("id" in resp and resp["id"] == id_, f"{what}: expected id {id_!r}, got {short(resp)}")
    return err


# --------------------------------------------------------------------------------------------
# The tests


class Context:
    def __init__(self, springfitd, springfit, source):
        self.springfitd = springfitd
        self.springfit = springfit
        self.source = source
        self.tmp = tempfile.mkdtemp(prefix="springfit-protocol-test-")
        self.daemons = []
        with open(os.path.join(source, "examples", "paper-iso-5x5.json")) as f:
            self.small_scene = json.load(f)
        with open(os.path.join(source, "examples", "kidney-2d.json")) as f:
            self.long_scene = json.load(f)
        self.long_scene["search"] = {"strategy": "paper", "max_generations": 200}
        with open(os.path.join(source, "tests", "data", "invalid-index.json")) as f:
            self.invalid_scene = json.load(f)
        self.main = None
        self.token_daemon = None
        self.before_job = None   # (job_id, result) of a job finished before the corpus
        self.long_jobs = []      # kidney jobs to cancel after the corpus

    def daemon(self, name, extra=()):
        d = Daemon(self.springfitd, self.tmp, name, extra)
        self.daemons.append(d)
        return d.start()

    def cleanup(self):
        for d in self.daemons:
            if d.alive():
                R.current = "cleanup"
                R.expect(d.stop(), f"daemon {d.name} did not exit within {STOP_TIMEOUT}s of SIGTERM")
        shutil.rmtree(self.tmp, ignore_errors=True)


def test_setup(ctx):
    ctx.main = ctx.daemon("main")
    with Conn(ctx.main.port) as c:
        info = c.result("server.info")
        R.expect(info.get("name") == "springfitd" and info.get("protocol") == 1 and
                 info.get("auth_required") is False and info.get("workers") == 2,
                 f"server.info: {short(info)}")
        # A job that finishes before the corpus; its result is compared after it.
        sub = c.result("job.submit", {"scene": ctx.small_scene, "label": "before-corpus", "seed": 3})
        require(sub.get("created") is True and isinstance(sub["job"].get("job_id"), int),
                f"job.submit: {short(sub)}")
        job_id = sub["job"]["job_id"]
        job = wait_state(c, job_id, ("succeeded", "failed", "cancelled"), 15, interval=0.02)
        require(job["state"] == "succeeded", f"job {job_id} before the corpus: {short(job)}")
        fields = {"job_id", "label", "priority", "seed", "idempotency_key", "state", "error", "scene", "genes",
                  "strategy", "max_generations", "created_at", "started_at", "finished_at", "progress",
                  "checkpoint_generation", "exact"}
        R.expect(fields <= set(job), f"job.get lacks documented fields {sorted(fields - set(job))}")
        R.expect(job.get("label") == "before-corpus" and job.get("seed") == 3 and job.get("priority") == 0 and
                 job.get("scene") == "paper-iso-5x5" and job.get("idempotency_key") is None and
                 job.get("error") is None and isinstance(job.get("exact"), bool),
                 f"job.get of a finished job: {short(job, 600)}")
        result = c.result("job.result", {"job_id": job_id})
        require("springs" in result and "cost" in result, f"job.result lacks springs/cost: {short(result)}")
        R.expect(result.get("job_id") == job_id and result.get("state") == "succeeded",
                 f"job.result carries job_id and state: {short(result)}")
        ctx.before_job = (job_id, result)


def test_framing(ctx):
    port = ctx.main.port
    info_req = b'{"jsonrpc":"2.0","id":1,"method":"server.info"}'
    with Conn(port) as c:
        # One request per line.
        c.send(info_req + b"\n")
        r = c.read()
        R.expect(r.get("id") == 1 and r.get("result", {}).get("name") == "springfitd",
                 f"one line: {short(r)}")
        # A pretty-printed request over several lines.
        pretty = json.dumps({"jsonrpc": "2.0", "id": "pretty", "method": "job.list",
                             "params": {"label": "no-such-label", "limit": 5}}, indent=2)
        require(pretty.count("\n") >= 5, "the pretty request spans lines")
        c.send(pretty.encode() + b"\n")
        r = c.read()
        R.expect(r.get("id") == "pretty" and r.get("result", {}).get("jobs") == [],
                 f"pretty-printed request: {short(r)}")
        # Three requests in one send: three answers, in order.
        three = (b'{"jsonrpc":"2.0","id":"a","method":"server.info"}\n'
                 b'{"jsonrpc":"2.0","id":"b","method":"job.get","params":{"job_id":987654321}}\n'
                 b'{"jsonrpc":"2.0","id":"c","method":"job.list","params":{"limit":1}}\n')
        c.send(three)
        answers = [c.read() for _ in range(3)]
        R.expect([a.get("id") for a in answers] == ["a", "b", "c"],
                 f"three in one send: ids {[a.get('id') for a in answers]}")
        R.expect("result" in answers[0] and answers[1].get("error", {}).get("code") == -32002 and
                 "result" in answers[2], f"three in one send: {short(answers, 600)}")
        R.expect(c.silent(0.2), f"three in one send: more than three answers: {short(c.buf)}")
        # Whitespace between messages is ignored; messages back to back on one line.
        c.send(b'  \r\n\t{"jsonrpc":"2.0","id":"x","method":"server.info"}'
               b'{"jsonrpc":"2.0","id":"y","method":"server.info"}  \n')
        R.expect([c.read().get("id"), c.read().get("id")] == ["x", "y"], "back-to-back messages")
    # A bare request without a trailing newline (nothing else is sent).
    with Conn(port) as c:
        c.send(b'{"jsonrpc":"2.0","id":"bare","method":"server.info"}')
        r = c.read()
        R.expect(r.get("id") == "bare" and "result" in r, f"bare request: {short(r)}")
        # ... and the connection goes on.
        c.send(b'{"jsonrpc":"2.0","id":"bare2","method":"server.info"}')
        r = c.read()
        R.expect(r.get("id") == "bare2" and "result" in r, f"second bare request: {short(r)}")
    # A request sent byte by byte: no answer before its last byte, then the answer.
    with Conn(port) as c:
        c.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        msg = b'{"jsonrpc":"2.0","id":"bytes","method":"job.get","params":{"job_id":987654321}}'
        for b in msg[:-1]:
            c.send(bytes([b]))
            time.sleep(0.003)
        R.expect(c.silent(0.3), f"answered before the message was complete: {short(c.buf)}")
        c.send(msg[-1:])
        r = c.read()
        R.expect(r.get("id") == "bytes" and r.get("error", {}).get("code") == -32002,
                 f"byte by byte: {short(r)}")
        # A response is one line even when its request spanned many TCP segments.
        R.expect(c.silent(0.1), f"extra output after the byte-by-byte answer: {short(c.buf)}")


def test_corpus(ctx):
    """Malformed and invalid input on ONE connection; after each, a probe must be answered."""
    port = ctx.main.port
    # Jobs in each state for the wrong-state errors: two long jobs fill both running slots,
    # a third waits.
    with Conn(port) as c:
        for i in range(3):
            sub = c.result("job.submit", {"scene": ctx.long_scene, "label": "long", "seed": 10 + i})
            ctx.long_jobs.append(sub["job"]["job_id"])
        running = [wait_state(c, j, ("running", "succeeded", "failed", "cancelled"), 5, interval=0.02)
                   for j in ctx.long_jobs[:2]]
        require(all(j["state"] == "running" for j in running),
                f"the two long jobs run: {[j['state'] for j in running]}")
        queued = c.result("job.get", {"job_id": ctx.long_jobs[2]})
        require(queued["state"] == "queued", f"the third long job waits: {queued['state']}")
    run_id, queued_id = ctx.long_jobs[0], ctx.long_jobs[2]

    scene_text = json.dumps(ctx.small_scene)
    require("[0.0, 0.0]" in scene_text, "the scene has a [0.0, 0.0] node to replace")
    nan_scene = scene_text.replace("[0.0, 0.0]", "[NaN, 0.0]", 1).encode()

    def req(id_, method, params_text=None):
        text = '{"jsonrpc":"2.0","id":%s,"method":"%s"' % (json.dumps(id_), method)
        if params_text is not None:
            text += ',"params":' + params_text
        return (text + "}").encode()

    deep = b"[" * 100 + b"]" * 100
    # (name, bytes to send, [(code, id, data checks)...] answers expected before the probe)
    # An expected answer of ("batch", ...) is checked by a function instead.
    cases = [
        ("garbage line", b"hello world\n", [(-32700, None, {})]),
        ("garbage before a request on one line (the rest of the line is dropped)",
         b'hello {"jsonrpc":"2.0","id":"hidden","method":"server.info"}\n', [(-32700, None, {})]),
        ("{{ line", b"{{\n", [(-32700, None, {})]),
        ("truncated JSON", b'{"jsonrpc":"2.0",]\n', [(-32700, None, {})]),
        ("truncated inside a string (raw newline)", b'{"jsonrpc":"2.0","id":1,"meth\n',
         [(-32700, None, {})]),
        ("invalid escape", req(1, "server.info", '{"a":"\\q"}') + b"\n", [(-32700, None, {})]),
        ("number with a leading zero", b'{"jsonrpc":"2.0","id":01,"method":"server.info"}\n',
         [(-32700, None, {})]),
        ("job_id as a string", req(2, "job.get", '{"job_id":"1"}') + b"\n",
         [(-32602, 2, {"path": "params.job_id"})]),
        ("positional params", req(3, "job.get", "[1]") + b"\n", [(-32602, 3, {})]),
        ("job_id 99999999999999999999", req(5, "job.get", '{"job_id":99999999999999999999}') + b"\n",
         [(-32602, 5, {"path": "params.job_id"})]),
        ("unknown param", req(6, "job.get", '{"job_id":1,"bogus":2}') + b"\n",
         [(-32602, 6, {"path": "params.bogus"})]),
        ("missing param", req(7, "job.get", "{}") + b"\n", [(-32602, 7, {"path": "params.job_id"})]),
        ("server.info with an unknown param", req(8, "server.info", '{"bogus":1}') + b"\n",
         [(-32602, 8, {"path": "params.bogus"})]),
        ("nesting 100 levels", req(9, "server.info", '{"x":' + deep.decode() + "}") + b"\n",
         [(-32700, None, {})]),
        ("invalid UTF-8 in a string", req(10, "job.list", '{"label":"') + b'\xff\xfe\xc3"}}\n',
         [(-32700, None, {})]),
        ("unknown method", req(11, "no.such.method") + b"\n", [(-32601, 11, {})]),
        ("missing jsonrpc", b'{"id":12,"method":"server.info"}\n', [(-32600, 12, {})]),
        ("jsonrpc 1.0", b'{"jsonrpc":"1.0","id":13,"method":"server.info"}\n', [(-32600, 13, {})]),
        ("method not a string", b'{"jsonrpc":"2.0","id":14,"method":5}\n', [(-32600, 14, {})]),
        ("unknown member", b'{"jsonrpc":"2.0","id":15,"method":"server.info","x":1}\n',
         [(-32600, 15, {})]),
        ("not an object", b'"hello"\n', [(-32700, None, {})]),
        ("id an object", b'{"jsonrpc":"2.0","id":{"a":1},"method":"server.info"}\n', [(-32600, None, {})]),
        ("empty batch", b"[]\n", [(-32600, None, {})]),
        ("NaN in a scene",
         b'{"jsonrpc":"2.0","id":16,"method":"job.submit","params":{"scene":' + nan_scene + b"}}\n",
         [(-32700, None, {})]),
        ("out-of-range node index",
         json.dumps({"jsonrpc": "2.0", "id": 17, "method": "job.submit",
                     "params": {"scene": ctx.invalid_scene}}).encode() + b"\n",
         [(-32003, 17, {"path": "reference.springs[5][1]"})]),
        ("per-spring stiffness asked of a GA",
         json.dumps({"jsonrpc": "2.0", "id": 23, "method": "job.submit",
                     "params": {"scene": dict(ctx.small_scene, search={"strategy": "hybrid",
                                                               "identify": "topology_and_stiffness"})}}).encode() + b"\n",
         [(-32003, 23, {"path": "search.identify"})]),
        ("unknown job", req(18, "job.get", '{"job_id":987654321}') + b"\n",
         [(-32002, 18, {"job_id": 987654321})]),
        ("job.result of a running job", req(19, "job.result", '{"job_id":%d}' % run_id) + b"\n",
         [(-32006, 19, {"state": "running"})]),
        ("job.result of a queued job", req(20, "job.result", '{"job_id":%d}' % queued_id) + b"\n",
         [(-32006, 20, {"state": "queued"})]),
        ("job.delete of a running job", req(21, "job.delete", '{"job_id":%d}' % run_id) + b"\n",
         [(-32006, 21, {"state": "running"})]),
        ("job.delete of a queued job", req(22, "job.delete", '{"job_id":%d}' % queued_id) + b"\n",
         [(-32006, 22, {"state": "queued"})]),
        ("notification alone", b'{"jsonrpc":"2.0","method":"server.info"}\n', []),
        ("notification of an unknown method", b'{"jsonrpc":"2.0","method":"no.such.method"}\n', []),
        ("notification with bad params", b'{"jsonrpc":"2.0","method":"job.get","params":{"job_id":"x"}}\n',
         []),
        ("batch of notifications only", b'[{"jsonrpc":"2.0","method":"server.info"}]\n', []),
    ]

    with Conn(port) as c:
        for n, (name, data, expected) in enumerate(cases):
            R.current = f"corpus: {name}"
            c.send(data)
            for code, id_, data_checks in expected:
                resp = c.read(what=f"error {code}")
                err = expect_error(resp, code, name, id_)
                d = error_data(err)
                for key, value in data_checks.items():
                    R.expect(d.get(key) == value, f"{name}: expected data.{key} = {value!r}, got {short(err)}")
            probe_id = f"probe-{n}"
            c.send(req(probe_id, "server.info") + b"\n")
            resp = c.read(what="the probe's answer")
            R.expect(resp.get("id") == probe_id and "result" in resp,
                     f"{name}: expected the probe's answer next, got {short(resp)}")

        # job_id 1e400: malformed (a number overflowing a double, SCENE.md) or out of range.
        R.current = "corpus: job_id 1e400"
        c.send(req(4, "job.get", '{"job_id":1e400}') + b"\n")
        resp = c.read()
        ok = R.expect(isinstance(resp.get("error"), dict) and resp["error"].get("code") in (-32700, -32602),
                      f"job_id 1e400: expected -32700 or -32602, got {short(resp)}")
        if ok:
            R.expect(resp["id"] == (None if resp["error"]["code"] == -32700 else 4),
                     f"job_id 1e400: id of the error: {short(resp)}")
        c.send(req("probe-1e400", "server.info") + b"\n")
        resp = c.read()
        R.expect(resp.get("id") == "probe-1e400", f"after 1e400: {short(resp)}")

        # Exactly 64 levels are allowed, 65 are not ({ params { job_id [...] } }).
        R.current = "corpus: nesting limit"
        c.send(req("d64", "job.get", '{"job_id":' + "[" * 62 + "]" * 62 + "}") + b"\n")
        expect_error(c.read(), -32602, "64 levels deep", "d64")
        c.send(req("d65", "job.get", '{"job_id":' + "[" * 63 + "]" * 63 + "}") + b"\n")
        expect_error(c.read(), -32700, "65 levels deep", None)

        # A batch of a valid request, an invalid one and a notification: two answers.
        R.current = "corpus: mixed batch"
        c.send(b'[{"jsonrpc":"2.0","id":"ok","method":"server.info"},'
               b'{"jsonrpc":"2.0","id":"bad"},'
               b'{"jsonrpc":"2.0","method":"server.info"}]\n')
        resp = c.read()
        if R.expect(isinstance(resp, list) and len(resp) == 2,
                    f"mixed batch: expected an array of exactly 2 answers, got {short(resp)}"):
            by_id = {a.get("id"): a for a in resp if isinstance(a, dict)}
            R.expect("result" in by_id.get("ok", {}), f"mixed batch: the valid request's answer: {short(resp)}")
            expect_error(by_id.get("bad"), -32600, "mixed batch: the invalid member", "bad")
        c.send(req("probe-batch", "server.info") + b"\n")
        resp = c.read()
        R.expect(resp.get("id") == "probe-batch", f"after the batch: {short(resp)}")

        # Members of a batch that are not objects: one -32600 each.
        R.current = "corpus: batch of non-objects"
        c.send(b'[1,"x"]\n')
        resp = c.read()
        if R.expect(isinstance(resp, list) and len(resp) == 2, f"[1,\"x\"]: expected 2 answers, got {short(resp)}"):
            for a in resp:
                expect_error(a, -32600, "[1,\"x\"] member", None)
        # id null is a request (RPC.md: id a string, a number or null), not a notification.
        R.current = "corpus: id null"
        c.send(b'{"jsonrpc":"2.0","id":null,"method":"server.info"}\n')
        resp = c.read(what="the answer to a request with id null")
        R.expect(resp.get("id", "absent") is None and "result" in resp, f"id null: {short(resp)}")

        # Batch limit (server.info limits.max_batch = 100): 101 members -> -32004 max_batch.
        R.current = "corpus: batch limit"
        batch = "[" + ",".join('{"jsonrpc":"2.0","id":%d,"method":"server.info"}' % i
                               for i in range(101)) + "]\n"
        c.send(batch.encode())
        resp = c.read()
        err = expect_error(resp, -32004, "101-member batch", None, check_id=False)
        R.expect(error_data(err).get("limit") == "max_batch", f"101-member batch: data.limit: {short(resp)}")
        c.send(req("probe-bl", "server.info") + b"\n")
        R.expect(c.read().get("id") == "probe-bl", "after the batch limit")

        R.current = "corpus: end"
        R.expect(c.silent(0.2), f"unexpected extra output at the end of the corpus: {short(c.buf)}")

    # The long jobs are no longer needed.
    R.current = "corpus: cancel long jobs"
    with Conn(port) as c:
        r = c.result("job.cancel", {"job_id": queued_id})
        R.expect(r.get("state") == "cancelled", f"cancelling a queued job: {short(r)}")
        for j in ctx.long_jobs[:2]:
            r = c.result("job.cancel", {"job_id": j})
            R.expect(r.get("state") in ("cancelling", "cancelled"), f"cancelling a running job: {short(r)}")
        resp = c.call("job.result", {"job_id": queued_id})
        expect_error(resp, -32006, "job.result of a job cancelled before it ran", resp.get("id"))


def test_after_corpus(ctx):
    R.expect(ctx.main.alive(), f"the daemon died: {short(ctx.main.stderr_text(), 500)}")
    job_id, before = ctx.before_job
    with Conn(ctx.main.port) as c:
        job = c.result("job.get", {"job_id": job_id})
        R.expect(job.get("state") == "succeeded" and job.get("label") == "before-corpus",
                 f"job {job_id} after the corpus: {short(job)}")
        after = c.result("job.result", {"job_id": job_id})
        R.expect(after.get("springs") == before["springs"] and after.get("cost") == before["cost"],
                 f"job {job_id}'s result changed: {short(before)} -> {short(after)}")
        # job.watch of a finished job: the job, then job.finished at once.
        watched = c.result("job.watch", {"job_id": job_id})
        R.expect(watched.get("job_id") == job_id and watched.get("state") == "succeeded",
                 f"job.watch of a finished job: {short(watched)}")
        note = c.read(what="job.finished")
        R.expect(note.get("method") == "job.finished" and "id" not in note and
                 note.get("params", {}).get("job_id") == job_id and
                 note.get("params", {}).get("state") == "succeeded",
                 f"job.watch of a finished job: expected a job.finished notification, got {short(note)}")
        R.expect(c.silent(0.2), f"job.watch of a finished job: more output: {short(c.buf)}")


def test_oversize(ctx):
    d = ctx.daemon("oversize", ["--max-message-bytes", "4096"])
    with Conn(d.port) as other, Conn(d.port) as c:
        require("result" in other.call("server.info"), "a second connection works")
        msg = (b'{"jsonrpc":"2.0","id":1,"method":"job.list","params":{"label":"' + b"x" * 10000 + b'"}}\n')
        require(len(msg) > 10000, "10 kB message")
        try:
            c.send(msg)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the server may close before reading everything; its answer is still read below
        resp = c.read(what="the -32004 error")
        err = expect_error(resp, -32004, "10 kB message", None)
        R.expect(error_data(err).get("limit") == "max_message_bytes",
                 f"10 kB message: expected data.limit max_message_bytes, got {short(resp)}")
        R.expect(error_data(err).get("max") == 4096, f"10 kB message: expected data.max 4096: {short(resp)}")
        R.expect(c.wait_closed(IO_TIMEOUT), "the server did not close the connection after -32004")
        # The other connection goes on, with a message just under the limit (whitespace counts).
        head = b'{"jsonrpc":"2.0","id":"near","method":"server.info"'
        near = head + b" " * (4060 - len(head) - 2) + b"}\n"
        require(4000 < len(near) < 4096, "a message just under the limit")
        other.send(near)
        r = other.read()
        R.expect(r.get("id") == "near" and "result" in r,
                 f"the other connection after the over-size message: {short(r)}")
    R.expect(d.alive(), "the daemon died")


def test_auth(ctx):
    token_file = os.path.join(ctx.tmp, "token.txt")
    with open(token_file, "w") as f:
        f.write(TOKEN + "\n")
    os.chmod(token_file, 0o600)
    d = ctx.token_daemon = ctx.daemon("token", ["--token-file", token_file])
    with Conn(d.port) as c, Conn(d.port) as other:
        resp = c.call("job.list")
        expect_error(resp, -32001, "job.list without auth", resp["id"])
        info = c.result("server.info")
        R.expect(info.get("auth_required") is True, f"server.info: auth_required: {short(info)}")
        resp = c.call("session.auth", {"token": WRONG_TOKEN})
        expect_error(resp, -32001, "session.auth with a wrong token", resp["id"])
        resp = c.call("job.get", {"job_id": 1})
        expect_error(resp, -32001, "job.get after a wrong token", resp["id"])
        r = c.result("session.auth", {"token": TOKEN})
        R.expect(r == {"authenticated": True}, f"session.auth: {short(r)}")
        r = c.result("job.list")
        R.expect(r.get("jobs") == [] and r.get("next_cursor") is None, f"job.list after auth: {short(r)}")
        # Before session.auth only small messages are taken: a large one is refused unread
        # (and the connection closed), not buffered and parsed for a client without the token.
        with Conn(d.port) as big:
            # server.info needs no token: only the size is refused here.
            msg = b'{"jsonrpc":"2.0","id":1,"method":"server.info"' + b" " * 200000 + b'}\n'
            try:
                big.send(msg)
            except (BrokenPipeError, ConnectionResetError):
                pass
            resp = big.read(what="the -32004 error before auth")
            err = expect_error(resp, -32004, "a 200 kB message before session.auth", None)
            R.expect(error_data(err).get("limit") == "max_unauthenticated_message_bytes"
                     and error_data(err).get("max") == 65536,
                     f"200 kB before auth: data names the bound: {short(resp)}")
            R.expect("before session.auth" in err.get("message", ""),
                     f"200 kB before auth: the message says why: {short(resp)}")
            R.expect(big.wait_closed(IO_TIMEOUT), "the connection was not closed after -32004")
        # Once authenticated, the same message is taken (and answered).
        c.send(b'{"jsonrpc":"2.0","id":"big","method":"server.info"' + b" " * 200000 + b'}\n')
        resp = c.read(what="the answer to a 200 kB message after auth")
        R.expect(resp.get("id") == "big" and "result" in resp,
                 f"200 kB after auth: {short(resp)}")
        # Authentication belongs to one connection.
        resp = other.call("job.list")
        expect_error(resp, -32001, "job.list on another, unauthenticated connection", resp["id"])
        # A batch is checked member by member.
        other.send(b'[{"jsonrpc":"2.0","id":1,"method":"server.info"},'
                   b'{"jsonrpc":"2.0","id":2,"method":"job.list"}]\n')
        resp = other.read()
        if R.expect(isinstance(resp, list) and len(resp) == 2, f"batch without auth: {short(resp)}"):
            by_id = {a.get("id"): a for a in resp}
            R.expect("result" in by_id.get(1, {}), f"batch: server.info answered: {short(resp)}")
            expect_error(by_id.get(2), -32001, "batch: job.list without auth", 2)

    # A non-loopback address without a token: refuses to start.
    bad_dir = os.path.join(ctx.tmp, "public")
    os.makedirs(bad_dir)
    with open(os.path.join(bad_dir, "stderr"), "wb") as err:
        proc = subprocess.Popen([ctx.springfitd, "--listen", "0.0.0.0:0", "--db",
                                 os.path.join(bad_dir, "test.db"), "--port-file",
                                 os.path.join(bad_dir, "port"), "--workers", "2"],
                                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err)
        try:
            code = proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)
            code = None
    with open(os.path.join(bad_dir, "stderr"), "rb") as f:
        stderr = f.read().decode("utf-8", "replace")
    R.expect(code is not None and code != 0,
             f"springfitd --listen 0.0.0.0:0 without a token: expected a non-zero exit, got {code}")
    R.expect("token" in stderr.lower(), f"springfitd --listen 0.0.0.0:0: stderr names the token: {short(stderr)}")
    R.expect(not os.path.exists(os.path.join(bad_dir, "port")), "0.0.0.0 without a token wrote a port file")


def test_trickle(ctx):
    """A message sent a byte at a time is cut off at --message-seconds, though every byte
    resets the idle clock; a whole message on another connection is answered meanwhile and
    after."""
    slow = ctx.daemon("trickle", ["--message-seconds", "1"])
    sock = socket.create_connection(("127.0.0.1", slow.port), timeout=IO_TIMEOUT)
    closed = False
    t0 = time.monotonic()
    text = b'{"jsonrpc":"2.0","id":1,"method":"server.info","params":{}}'
    try:
        for byte in text[:-1]:
            sock.sendall(bytes([byte]))
            time.sleep(0.1)
            if time.monotonic() - t0 > 4:
                break
        sock.settimeout(3)
        closed = sock.recv(100) == b""
    except (BrokenPipeError, ConnectionResetError):
        closed = True
    except socket.timeout:
        closed = False
    sock.close()
    R.expect(closed, "a message trickled a byte every 0.1 s was never cut off")
    # Half a message, then silence: cut off at --message-seconds too, not at the idle timeout
    # (300 s; never, while the connection watched a job).
    sock = socket.create_connection(("127.0.0.1", slow.port), timeout=IO_TIMEOUT)
    sock.sendall(text[:20])
    t1 = time.monotonic()
    sock.settimeout(4)
    try:
        closed = sock.recv(100) == b""
    except socket.timeout:
        closed = False
    except ConnectionResetError:
        closed = True
    waited = time.monotonic() - t1
    sock.close()
    R.expect(closed and waited < 4, f"half a message and then silence: closed {closed} after {waited:.1f} s "
             "(expected closed within 4 s at --message-seconds 1)")
    with Conn(slow.port) as c:
        R.expect(c.result("server.info").get("name") == "springfitd",
                 "a whole message is not answered after the trickle")


def test_connection_limit(ctx):
    d = ctx.daemon("connlimit", ["--max-connections", "2"])
    a = Conn(d.port)
    b = Conn(d.port)
    try:
        require("result" in a.call("server.info"), "first connection works")
        require("result" in b.call("server.info"), "second connection works")
        with Conn(d.port) as c:
            resp = c.read(what="the -32005 error on the third connection")
            expect_error(resp, -32005, "third connection", None)
            R.expect(c.wait_closed(IO_TIMEOUT), "the third connection was not closed")
        a.close()
        # The server notices the close asynchronously: retry a few times, bounded.
        deadline = time.monotonic() + 3
        worked = False
        last = None
        while not worked and time.monotonic() < deadline:
            with Conn(d.port) as n:
                n.send(b'{"jsonrpc":"2.0","id":"new","method":"server.info"}\n')
                line = n.read_raw_line(IO_TIMEOUT)
                last = line
                if line is not None:
                    r = json.loads(line)
                    worked = r.get("id") == "new" and "result" in r
            if not worked:
                time.sleep(0.05)
        R.expect(worked, f"after closing one connection a new one works: last answer {short(last)}")
        R.expect("result" in b.call("server.info"), "the remaining connection still works")
    finally:
        a.close()
        b.close()


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


def run_cli(ctx, *args):
    env = {k: v for k, v in os.environ.items() if not k.startswith("SPRINGFIT_")}
    try:
        p = subprocess.run([ctx.springfit] + list(args), stdin=subprocess.DEVNULL, capture_output=True,
                           timeout=CLI_TIMEOUT, env=env, cwd=ctx.source)
    except subprocess.TimeoutExpired:
        return None, "", "(timed out)"
    return p.returncode, p.stdout.decode("utf-8", "replace"), p.stderr.decode("utf-8", "replace")


def test_cli(ctx):
    server = f"127.0.0.1:{ctx.main.port}"

    def expect_exit(want, *args):
        code, out, err = run_cli(ctx, *args)
        R.expect(code == want, f"springfit {' '.join(args)}: exit {code}, expected {want} (stderr: {short(err)})")
        return code, out, err

    expect_exit(4, "status", "999999", "--server", server)
    code, _, err = expect_exit(5, "info", "--server", "127.0.0.1:1")
    R.expect(err.strip() != "" and len(err.rstrip("\n").split("\n")) == 1,
             f"springfit info against a closed port: expected one stderr line, got {err!r}")
    expect_exit(2, "submit", os.path.join(ctx.source, "tests", "data", "invalid-index.json"), "--server", server)
    expect_exit(0, "info", "--server", server)
    require(ctx.token_daemon is not None and ctx.token_daemon.alive(), "no token daemon (see auth)")
    token_server = f"127.0.0.1:{ctx.token_daemon.port}"
    expect_exit(6, "list", "--server", token_server)
    expect_exit(6, "status", "1", "--server", token_server)
    token_file = os.path.join(ctx.tmp, "token.txt")
    expect_exit(0, "list", "--server", token_server, "--token-file", token_file)


def main(argv):
    groups = [
        ("setup", test_setup, True),
        ("framing", test_framing, False),
        ("corpus", test_corpus, False),
        ("after corpus", test_after_corpus, False),
        ("over-size", test_oversize, False),
        ("auth", test_auth, False),
        ("connection limit", test_connection_limit, False),
        ("trickle", test_trickle, False),
        ("idempotency race", test_idempotency_race, False),
        ("load", test_load, False),
        ("cli", test_cli, False),
    ]
    return run_suite(argv, __doc__.strip().split("\n\n")[1], Context, groups,
                     lambda daemon: daemon.stderr_text())


if __name__ == "__main__":
    sys.exit(main(sys.argv))
