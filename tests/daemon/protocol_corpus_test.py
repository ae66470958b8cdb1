#!/usr/bin/env python3
"""Outside-in test of springfitd against malformed and invalid JSON-RPC input (proto/RPC.md).

Usage: protocol_corpus_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts springfitd on 127.0.0.1 with a free port in a temporary directory and checks, against
the documented behaviour: the malformed-input corpus on one connection (each answered with its
error code, id and data, the connection surviving), the nesting and batch limits, and then
the daemon and a job finished before the corpus (its result unchanged, job.watch of it).
Python 3 standard library only (the shared part: protocol_support.py).

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import json
import sys

sys.dont_write_bytecode = True  # no __pycache__ in the source tree for harness.py
from harness import Conn, R, error_data, require, short, wait_state  # noqa: E402
from protocol_support import expect_error, run_groups, test_setup  # noqa: E402


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


if __name__ == "__main__":
    sys.exit(run_groups(sys.argv, __doc__, [
        ("setup", test_setup, True),
        ("corpus", test_corpus, False),
        ("after corpus", test_after_corpus, False),
    ]))
