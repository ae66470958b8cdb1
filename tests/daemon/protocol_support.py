"""The shared part of the outside-in tests of springfitd's JSON-RPC/TCP protocol
(protocol_framing_test.py, protocol_corpus_test.py, protocol_limits_test.py,
protocol_auth_test.py and protocol_load_test.py; proto/RPC.md).

The documented error codes, compact JSON required of every response line (Conn.check_compact),
error answers checked (expect_error), the Context (daemons in a temporary directory, stopped at
the end), the setup group that starts the main daemon and runs a job to its end, and
run_groups, which runs a script's groups (harness.run_suite). Python 3 standard library only.
"""

import json
import os
import shutil
import tempfile

from harness import STOP_TIMEOUT, Conn, Daemon, R, require, run_suite, short, wait_state

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
# The context and the setup group


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


def run_groups(argv, doc, groups):
    """Runs a test script's groups (harness.run_suite) with this Context; doc is the script's
    docstring, whose second paragraph is its usage."""
    return run_suite(argv, doc.strip().split("\n\n")[1], Context, groups,
                     lambda daemon: daemon.stderr_text())
