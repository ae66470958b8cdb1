#!/usr/bin/env python3
"""End-to-end test of springfitd's preparation of large submissions, and of the client's view.

Usage: client_preparation_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts daemons on 127.0.0.1 with a free port in a temporary directory and checks: server.info
answered while two 14,400-node submissions are prepared on their own threads (also when one
spells its method with a JSON escape), and the `preparing` state: listed, announced to its
submitter (job.preparing), cancellable (also through `springfit submit`), dropped when its
submitter goes away or the daemon is killed. Python 3 standard library only (the shared part:
client_support.py).

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import json
import os
import select
import subprocess
import sys
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree for harness.py
from harness import Conn, R, error_data, grid_scene, require, short  # noqa: E402
from client_support import run_groups  # noqa: E402


def test_preparation_threads(ctx):
    """Two 14,400-node submissions being prepared: server.info is answered meanwhile (it waited
    16.6 s), also when a submission spells its method with a JSON escape ("job\u002esubmit"):
    the daemon routes by the method it parsed, not by how the text spells it (a text match sent
    such a submission to a request thread, and two of them held both). --max-genes 10 refuses
    each submission once its scene is prepared, so that no job runs."""
    d = ctx.daemon("prepare", ["--max-genes", "10"])
    scene_text = json.dumps(grid_scene(120, "grid-120"), separators=(",", ":"))
    submissions = []
    try:
        for i, method in enumerate(("job\\u002esubmit", "job.submit")):
            c = Conn(d.port)
            submissions.append(c)
            c.send(('{"jsonrpc":"2.0","id":%d,"method":"%s","params":{"scene":%s,"label":"big-%d"}}\n'
                    % (i + 1, method, scene_text, i)).encode())
        latencies = []
        with Conn(d.port) as c:
            for _ in range(3):
                t0 = time.monotonic()
                info = c.result("server.info", timeout=60)
                latencies.append(time.monotonic() - t0)
                R.expect(info.get("name") == "springfitd", f"server.info: {short(info)}")
                time.sleep(0.05)
        pending = [not answered(c) for c in submissions]
        R.expect(all(pending), f"a submission was answered before server.info's three answers "
                               f"(pending: {pending}): nothing was shown")
        print(f"  server.info during two 14,400-node preparations: "
              f"{', '.join(f'{1000 * t:.1f} ms' for t in latencies)}", flush=True)
        for i, c in enumerate(submissions):
            resp = c.read_answer(timeout=120, what=f"the answer to submission {i + 1}")
            err = resp.get("error") or {}
            R.expect(err.get("code") == -32004 and error_data(err).get("limit") == "max_genes",
                     f"submission {i + 1}: expected the max_genes refusal after its preparation, "
                     f"got {short(resp)}")
    finally:
        for c in submissions:
            c.close()


def answered(conn):
    """True when an answer (not a job.preparing notification) has arrived on `conn`; the
    notifications read meanwhile are dropped."""
    while True:
        line = conn.read_raw_line(0.001)
        if line is None:
            return False
        if json.loads(line).get("method") != "job.preparing":
            conn.buf = line + b"\n" + conn.buf  # left for the reader of the answer
            return True


def wait_listed_preparing(c, label, timeout=60):
    """The id of the job labelled `label` once job.list shows it preparing, or None."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for job in c.result("job.list", {"state": "preparing", "label": label})["jobs"]:
            return job["job_id"]
        time.sleep(0.05)
    return None


def test_preparing_state(ctx):
    """A large submission is a job from the start of its preparation: listed `preparing`,
    announced to its submitter (job.preparing), and cancellable through job.cancel, which the
    submission's answer then reports (issue 15: a 316x316 grid took 22 s to prepare with no id
    and no way to stop it). A submitter that goes away, or a daemon killed meanwhile, leaves no
    job: the submission was never acknowledged."""
    d = ctx.daemon("preparing")
    scene_text = json.dumps(grid_scene(150, "grid-150"), separators=(",", ":"))

    def submit(label, key=None):
        conn = Conn(d.port)
        extra = ',"idempotency_key":"%s"' % key if key else ""
        conn.send(('{"jsonrpc":"2.0","id":1,"method":"job.submit","params":{"scene":%s,"label":"%s"%s}}\n'
                   % (scene_text, label, extra)).encode())
        return conn

    with Conn(d.port) as c:
        # Cancelled while it is prepared.
        sub = submit("prep-cancel")
        try:
            job_id = wait_listed_preparing(c, "prep-cancel")
            require(job_id is not None, "the submission was never listed as preparing")
            R.expect(c.result("job.get", {"job_id": job_id})["state"] == "preparing",
                     "job.get does not show the job preparing")
            R.expect(not answered(sub), "the submission was answered before it was cancelled")
            t0 = time.monotonic()
            answer = c.result("job.cancel", {"job_id": job_id})
            R.expect(answer.get("state") == "cancelling", f"job.cancel of a preparing job: {short(answer)}")
            notices = []
            while True:
                resp = sub.read(timeout=60, what="the cancelled submission's answer")
                if resp.get("method") != "job.preparing":
                    break
                notices.append(resp["params"])
            stopped = time.monotonic() - t0
            job = (resp.get("result") or {}).get("job") or {}
            R.expect(resp.get("id") == 1 and job.get("job_id") == job_id and job.get("state") == "cancelled",
                     f"the cancelled submission's answer: {short(resp)}")
            R.expect(all(n.get("job_id") == job_id for n in notices), f"job.preparing: {short(notices)}")
            stored = c.result("job.get", {"job_id": job_id})
            R.expect(stored["state"] == "cancelled", f"the job is not cancelled in the store: {short(stored)}")
            # Stopped inside its preparation, which therefore never counted its genes.
            R.expect(stored["genes"] == 0, f"the preparation ran to its end: {stored['genes']} genes")
            print(f"  a preparing job stopped {1000 * stopped:.0f} ms after job.cancel "
                  f"({len(notices)} job.preparing notices after it)", flush=True)
        finally:
            sub.close()

        # springfit submit prints the id once the preparation has taken a second (job.preparing),
        # and reports the cancel.
        scene_path = os.path.join(ctx.tmp, "grid-150.json")
        with open(scene_path, "w") as f:
            f.write(scene_text)
        env = {k: v for k, v in os.environ.items() if not k.startswith("SPRINGFIT_")}
        cli = subprocess.Popen([ctx.springfit, "submit", scene_path, "--label", "prep-cli",
                                "--server", f"127.0.0.1:{d.port}"], stdin=subprocess.DEVNULL,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
        try:
            # (bounded: a submit that never prints would otherwise hang the suite)
            ready, _, _ = select.select([cli.stderr], [], [], 60)
            first = cli.stderr.readline().decode("utf-8", "replace") if ready else "(nothing in 60 s)"
            listed = wait_listed_preparing(c, "prep-cli", timeout=1)
            R.expect(first.startswith(f"job {listed} preparing"),
                     f"springfit submit's first line while job {listed} is prepared: {short(first)}")
            c.result("job.cancel", {"job_id": listed})
            out, err = cli.communicate(timeout=60)
            R.expect(cli.returncode == 0 and out.decode().strip() == str(listed)
                     and f"job {listed} cancelled while it was prepared" in err.decode(),
                     f"springfit submit of a job cancelled while prepared: exit {cli.returncode}, "
                     f"stdout {short(out)}, stderr {short(err)}")
        finally:
            if cli.poll() is None:
                cli.kill()
                cli.wait()

        # Its submitter goes away: the job is dropped, and a watcher is told (job.gone).
        sub = submit("prep-gone", key="prep-gone-key")
        watcher = Conn(d.port)
        try:
            gone = wait_listed_preparing(c, "prep-gone")
            require(gone is not None, "the second submission was never listed as preparing")
            # A retry with its key meanwhile waits for the first one's outcome: here the first
            # submitter goes away, so the retry becomes the submission (checked below).
            retry = Conn(d.port)
            retry.send(('{"jsonrpc":"2.0","id":7,"method":"job.submit","params":{"scene":%s,'
                        '"label":"prep-retry","idempotency_key":"prep-gone-key"}}\n' % scene_text).encode())
            R.expect(not answered(retry), "the retry was answered while the first was prepared")
            watched = watcher.result("job.watch", {"job_id": gone})
            R.expect(watched.get("state") == "preparing", f"job.watch of a preparing job: {short(watched)}")
            cli_watch = subprocess.Popen([ctx.springfit, "watch", str(gone), "--server", f"127.0.0.1:{d.port}"],
                                         stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                         stderr=subprocess.PIPE, env=env)
            time.sleep(0.3)  # (its job.watch answered before the drop)
        finally:
            sub.close()
        try:
            resp = retry.read_answer(timeout=120, what="the retry's answer")
            job = (resp.get("result") or {}).get("job") or {}
            R.expect(resp.get("result", {}).get("created") is True and job.get("state") == "queued"
                     and job.get("job_id") not in (None, gone),
                     f"the retry of a dropped submission is not a new queued job: {short(resp)}")
            if job.get("job_id"):
                c.call("job.cancel", {"job_id": job["job_id"]})
            note = watcher.read(timeout=60, what="job.gone for the dropped submission")
            R.expect(note.get("method") == "job.gone" and note.get("params", {}).get("job_id") == gone,
                     f"the watcher of a dropped submission got {short(note)}")
            _, err = cli_watch.communicate(timeout=60)
            # (exit 4 either way: "no longer exists", or "no such job" if its job.watch came late)
            R.expect(cli_watch.returncode == 4 and ("no longer exists" in err.decode() or "no such job" in err.decode()),
                     f"springfit watch of a dropped submission: exit {cli_watch.returncode}, {short(err)}")
        finally:
            watcher.close()
            retry.close()
            if cli_watch.poll() is None:
                cli_watch.kill()
                cli_watch.wait()
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and "error" not in c.call("job.get", {"job_id": gone}):
            time.sleep(0.05)
        err = c.call("job.get", {"job_id": gone}).get("error") or {}
        R.expect(err.get("code") == -32002, f"job {gone}, whose submitter went away, is still there: {short(err)}")

        # The daemon killed while it prepares (the submitter still waiting): after the restart
        # the job is not there.
        sub = submit("prep-killed")
    try:
        with Conn(d.port) as c:
            killed = wait_listed_preparing(c, "prep-killed")
            require(killed is not None, "the third submission was never listed as preparing")
        d.kill9()
    finally:
        sub.close()
    d.start()
    with Conn(d.port) as c:
        err = c.call("job.get", {"job_id": killed}).get("error") or {}
        R.expect(err.get("code") == -32002, f"job {killed}, preparing at a kill -9, is there after the restart: {short(err)}")
        R.expect(c.result("job.list", {"state": "preparing"})["jobs"] == [], "preparing jobs after the restart")


if __name__ == "__main__":
    sys.exit(run_groups(sys.argv, __doc__, [
        ("preparation threads", test_preparation_threads, False),
        ("preparing state", test_preparing_state, False),
    ]))
