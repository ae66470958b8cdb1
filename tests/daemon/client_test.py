#!/usr/bin/env python3
"""End-to-end test of the springfit client against springfitd, and of the daemon's guards.

Usage: client_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts daemons on 127.0.0.1 with a free port in a temporary directory and checks: the client's
--timeout against a server that never answers, `submit --wait --json`, Ctrl-C on a watch
(the job keeps running), `list` paging and order, `trace --json`, idempotency keys reused for
another scene, token files readable by others or directories, wrong tokens on one connection,
the SQLite database's mode, numbers beyond the scene's bounds and the search's population
bound. Python 3 standard library only.

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import copy
import json
import os
import re
import resource
import select
import shutil
import signal
import socket
import sqlite3
import stat
import subprocess
import sys
import tempfile
import threading
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree for harness.py
from harness import (IO_TIMEOUT, grid_scene, STOP_TIMEOUT, Abort, Conn, Daemon, R, error_data, require, run_suite,
                     short, wait_state)

# IO_TIMEOUT (5 s), START_TIMEOUT (10 s) and STOP_TIMEOUT (15 s) are harness.py's.
CLI_TIMEOUT = 20.0        # for one springfit invocation
JOB_TIMEOUT = 20.0        # for a small job to finish
REFUSE_TIMEOUT = 5.0      # for a daemon refusing its arguments to exit

TOKEN = "0123456789abcdefABCDEF0123456789"        # 32 characters
WRONG_TOKEN = "0123456789abcdefABCDEF012345678X"  # same length, last character differs
FINAL_STATES = ("succeeded", "failed", "cancelled")


# --------------------------------------------------------------------------------------------
# Error answers and a daemon that refuses to start


def expect_error(resp, code, what):
    """Checks that resp is an error response with `code`; returns its error object or {}."""
    ok = R.expect(isinstance(resp, dict) and isinstance(resp.get("error"), dict),
                  f"{what}: expected error {code}, got {short(resp)}")
    if not ok:
        return {}
    err = resp["error"]
    R.expect(err.get("code") == code, f"{what}: expected code {code}, got {err.get('code')}: {short(resp)}")
    R.expect(isinstance(err.get("message"), str) and err["message"],
             f"{what}: error without a message: {short(resp)}")
    return err


def run_refused_daemon(ctx, name, args, setup=None):
    """Starts springfitd with `args` (after its listen, database and port file), expecting it to
    refuse to start; setup runs in the child first (limits). Returns (exit code or None when it
    was still running after REFUSE_TIMEOUT, stderr, port file written)."""
    d = os.path.join(ctx.tmp, name)
    os.makedirs(d)
    err_path = os.path.join(d, "stderr")
    port_file = os.path.join(d, "port")
    with open(err_path, "wb") as err:
        proc = subprocess.Popen([ctx.springfitd, "--listen", "127.0.0.1:0", "--db", os.path.join(d, "test.db"),
                                 "--port-file", port_file] + list(args),
                                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err, preexec_fn=setup)
        try:
            code = proc.wait(REFUSE_TIMEOUT)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)
            code = None
    with open(err_path, "rb") as f:
        text = f.read().decode("utf-8", "replace")
    return code, text, os.path.exists(port_file)


# --------------------------------------------------------------------------------------------
# The tests


class Context:
    def __init__(self, springfitd, springfit, source):
        self.springfitd = springfitd
        self.springfit = springfit
        self.source = source
        self.tmp = tempfile.mkdtemp(prefix="springfit-client-test-")
        self.daemons = []
        self.iso_path = os.path.join(source, "examples", "paper-iso-5x5.json")
        self.aniso_path = os.path.join(source, "examples", "paper-aniso-5x5.json")
        self.kidney_path = os.path.join(source, "examples", "kidney-2d.json")
        self.plate_path = os.path.join(source, "examples", "fem-plate-5x5.json")
        with open(self.iso_path) as f:
            self.small_scene = json.load(f)
        self.nonce = f"{os.getpid()}-{time.time_ns()}"
        self.main = None
        self.token_daemon = None
        self.watch_proc = None
        self.long_job = None

    def daemon(self, name, extra=()):
        d = Daemon(self.springfitd, self.tmp, name, extra)
        self.daemons.append(d)
        return d.start()

    def server(self):
        return f"127.0.0.1:{self.main.port}"

    def cleanup(self):
        R.current = "cleanup"
        if self.watch_proc is not None and self.watch_proc.poll() is None:
            self.watch_proc.kill()
            self.watch_proc.wait(5)
        if self.long_job is not None and self.main is not None and self.main.alive():
            try:
                with Conn(self.main.port) as c:
                    c.call("job.cancel", {"job_id": self.long_job})
            except (OSError, Abort):
                pass
        for d in self.daemons:
            if d.alive():
                R.expect(d.stop(), f"daemon {d.name} did not exit within {STOP_TIMEOUT}s of SIGTERM")
            else:
                d.close_files()
        shutil.rmtree(self.tmp, ignore_errors=True)


def run_cli(ctx, *args, timeout=CLI_TIMEOUT):
    """Runs springfit; (exit code or None on timeout, stdout, stderr, wall seconds)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("SPRINGFIT_")}
    t0 = time.monotonic()
    try:
        p = subprocess.run([ctx.springfit] + list(args), stdin=subprocess.DEVNULL, capture_output=True,
                           timeout=timeout, env=env, cwd=ctx.source)
    except subprocess.TimeoutExpired:
        return None, "", "(timed out)", time.monotonic() - t0
    return (p.returncode, p.stdout.decode("utf-8", "replace"), p.stderr.decode("utf-8", "replace"),
            time.monotonic() - t0)


def cli_desc(args):
    return "springfit " + " ".join(args)


def expect_exit(ctx, want, *args):
    code, out, err, _ = run_cli(ctx, *args)
    R.expect(code == want, f"{cli_desc(args)}: exit {code}, expected {want} (stdout: {short(out)}; "
                           f"stderr: {short(err)})")
    return code, out, err


def parse_json_output(text, what):
    """stdout that must be exactly one JSON value; the value, or None (reported)."""
    try:
        return json.loads(text)
    except ValueError as e:
        R.fail(f"{what}: stdout is not exactly one JSON value ({e}): {short(text)}")
        return None


def test_setup(ctx):
    ctx.main = ctx.daemon("main")
    with Conn(ctx.main.port) as c:
        info = c.result("server.info")
        require(info.get("name") == "springfitd" and info.get("auth_required") is False,
                f"server.info: {short(info)}")


def test_client_timeout(ctx):
    """A server that accepts connections and never answers: --timeout 1 ends the client."""
    listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    listener.bind(("127.0.0.1", 0))
    listener.listen(8)
    listener.settimeout(0.1)
    port = listener.getsockname()[1]
    stop = threading.Event()
    held = []

    def serve():
        while not stop.is_set():
            try:
                conn, _ = listener.accept()
                held.append(conn)  # kept open, never read from nor written to
            except socket.timeout:
                continue
            except OSError:
                return

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        args = ("info", "--server", f"127.0.0.1:{port}", "--timeout", "1")
        code, out, err, wall = run_cli(ctx, *args, timeout=10)
        R.expect(code == 5, f"{cli_desc(args)} against a silent server: exit {code}, expected 5 "
                            f"(stderr: {short(err)})")
        R.expect(wall < 5.0, f"{cli_desc(args)}: took {wall:.1f} s of wall time, expected < 5 s")
        lines = err.rstrip("\n").split("\n")
        R.expect(len(lines) == 1 and err.strip() != "",
                 f"{cli_desc(args)}: expected one stderr line, got {err!r}")
        R.expect("did not answer within 1 s" in err,
                 f"{cli_desc(args)}: stderr lacks 'did not answer within 1 s': {err!r}")
        R.expect(out == "", f"{cli_desc(args)}: unexpected stdout {out!r}")
        R.expect(len(held) >= 1, "the silent server saw no connection")
    finally:
        stop.set()
        thread.join(2)
        listener.close()
        for conn in held:
            conn.close()


def test_submit_wait(ctx):
    args = ("submit", ctx.iso_path, "--wait", "--json", "--label", f"wait-{ctx.nonce}", "--server", ctx.server())
    code, out, err = expect_exit(ctx, 0, *args)
    m = re.search(r"\bjob (\d+) queued\b", err)
    require(m, f"{cli_desc(args)}: stderr lacks 'job N queued': {err!r}")
    job_id = int(m.group(1))
    result = parse_json_output(out, cli_desc(args))
    if result is not None:
        R.expect(isinstance(result, dict) and result.get("job_id") == job_id,
                 f"{cli_desc(args)}: expected the result of job {job_id}, got {short(result)}")
        R.expect(isinstance(result, dict) and "springs" in result and result.get("state") == "succeeded",
                 f"{cli_desc(args)}: the result lacks springs or state succeeded: {short(result)}")


def test_submit_watch_phases(ctx):
    """submit --watch says what run says: the scene's notices before the job runs, and where a
    step has got between rows (job.phase), not only the rows."""
    scene = json.load(open(os.path.join(ctx.source, "examples", "fem-kidney-2d.json")))
    scene["reference"]["material"]["poisson"] = 0.495  # a notice: linear elements lock near 0.5
    scene["name"] = f"locking kidney {ctx.nonce}"
    path = os.path.join(ctx.tmp, "locking-kidney.json")
    json.dump(scene, open(path, "w"))
    args = ("submit", path, "--watch", "--server", ctx.server())
    code, out, err, _ = run_cli(ctx, *args, timeout=JOB_TIMEOUT)
    R.expect(code in (0, 12), f"{cli_desc(args)}: exit {code} (usable or doubtful) ({short(err)})")
    lines = err.splitlines()
    queued = next((i for i, l in enumerate(lines) if re.search(r"\bjob \d+ queued\b", l)), None)
    notices = [i for i, l in enumerate(lines) if l.startswith("springfit: notice: ") and "0.495" in l]
    R.expect(queued is not None and notices and notices[0] == queued + 1,
             f"{cli_desc(args)}: the scene's notice right after 'job N queued': {short(err, 1500)}")
    # The probe fit's phases (analysis, fit, ...) as run shows them: lines of the watched job.
    phases = [l for l in lines if re.search(r"\bphase\b|in progress|sparsity path", l)]
    R.expect(len(phases) >= 1, f"{cli_desc(args)}: no phase line while the job ran: {short(err, 1500)}")


def sigint_caught(pid):
    """True when the process has a handler for SIGINT (Linux /proc); None when unknown."""
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("SigCgt:"):
                    return bool(int(line.split()[1], 16) & (1 << (signal.SIGINT - 1)))
    except (OSError, ValueError):
        return None
    return None


def test_watch_interrupt(ctx):
    args = ("submit", ctx.kidney_path, "--strategy", "paper", "--generations", "100000",
            "--label", f"long-{ctx.nonce}", "--server", ctx.server())
    code, out, err = expect_exit(ctx, 0, *args)
    require(code == 0 and out.strip().isdigit(), f"{cli_desc(args)}: expected a job id on stdout, got {out!r}")
    job_id = ctx.long_job = int(out.strip())
    with Conn(ctx.main.port) as c:
        job = wait_state(c, job_id, ("running",) + FINAL_STATES, 10)
        require(job["state"] == "running", f"the long job {job_id} does not run: {short(job)}")

    watch_dir = os.path.join(ctx.tmp, "watch")
    os.makedirs(watch_dir)
    out_path, err_path = os.path.join(watch_dir, "stdout"), os.path.join(watch_dir, "stderr")
    env = {k: v for k, v in os.environ.items() if not k.startswith("SPRINGFIT_")}
    with open(out_path, "wb") as out_f, open(err_path, "wb") as err_f:
        ctx.watch_proc = subprocess.Popen([ctx.springfit, "watch", str(job_id), "--server", ctx.server()],
                                          stdin=subprocess.DEVNULL, stdout=out_f, stderr=err_f, env=env,
                                          cwd=ctx.source)
    proc = ctx.watch_proc
    # The watch installs its handler once connected; wait for it (bounded), else a moment.
    deadline = time.monotonic() + 5
    caught = sigint_caught(proc.pid)
    while caught is False and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
        caught = sigint_caught(proc.pid)
    if caught is None:
        time.sleep(1.0)
    time.sleep(0.3)  # let it be inside job.watch, receiving progress
    require(proc.poll() is None, f"springfit watch {job_id} ended before the interrupt: exit {proc.returncode}")
    t0 = time.monotonic()
    proc.send_signal(signal.SIGINT)
    try:
        code = proc.wait(5)
    except subprocess.TimeoutExpired:
        code = None
        proc.kill()
        proc.wait(5)
    wall = time.monotonic() - t0
    with open(err_path, "rb") as f:
        err = f.read().decode("utf-8", "replace")
    R.expect(code == 130, f"springfit watch {job_id} after SIGINT: exit {code} after {wall:.1f} s, "
                          f"expected 130 within 5 s (stderr tail: {err[-300:]!r})")
    R.expect(f"job {job_id} keeps running" in err,
             f"springfit watch {job_id} after SIGINT: stderr lacks 'job {job_id} keeps running': {err[-300:]!r}")
    R.expect(f"springfit cancel {job_id}" in err,
             f"springfit watch {job_id} after SIGINT: stderr lacks 'springfit cancel {job_id}': {err[-300:]!r}")

    # The job goes on.
    time.sleep(0.3)
    args = ("status", str(job_id), "--json", "--server", ctx.server())
    code, out, err = expect_exit(ctx, 0, *args)
    job = parse_json_output(out, cli_desc(args)) if code == 0 else None
    R.expect(isinstance(job, dict) and job.get("state") == "running",
             f"{cli_desc(args)} after the interrupted watch: expected state running, got {short(job)}")

    # Then it is cancelled.
    args = ("cancel", str(job_id), "--server", ctx.server())
    code, out, err = expect_exit(ctx, 0, *args)
    R.expect(f"job {job_id} cancel" in out, f"{cli_desc(args)}: stdout {out!r}")
    with Conn(ctx.main.port) as c:
        job = wait_state(c, job_id, FINAL_STATES, 10)
    R.expect(job["state"] == "cancelled", f"job {job_id} after springfit cancel: {short(job)}")
    if job["state"] in FINAL_STATES:
        ctx.long_job = None


def list_json(ctx, *extra):
    args = ("list",) + extra + ("--json", "--server", ctx.server())
    code, out, err = expect_exit(ctx, 0, *args)
    value = parse_json_output(out, cli_desc(args)) if code == 0 else None
    ok = R.expect(isinstance(value, dict) and set(value) == {"jobs", "next_cursor"} and
                  isinstance(value["jobs"], list),
                  f"{cli_desc(args)}: expected {{\"jobs\": [...], \"next_cursor\": ...}}, got {short(out)}")
    if not ok:
        return None, None
    return [j.get("job_id") for j in value["jobs"]], value["next_cursor"]


def test_list(ctx):
    label = f"list-{ctx.nonce}"
    ids = []
    for i in range(3):
        args = ("submit", ctx.iso_path, "--label", label, "--seed", str(20 + i), "--server", ctx.server())
        code, out, err = expect_exit(ctx, 0, *args)
        require(code == 0 and out.strip().isdigit(), f"{cli_desc(args)}: expected a job id, got {out!r}")
        ids.append(int(out.strip()))
    require(ids == sorted(ids) and len(set(ids)) == 3, f"job ids not increasing: {ids}")
    newest = sorted(ids, reverse=True)

    got, cursor = list_json(ctx, "--label", label)
    R.expect(got == newest, f"list --label: expected {newest} (newest first), got {got}")
    R.expect(got is None or cursor is None, f"list --label: expected next_cursor null, got {cursor!r}")

    got, cursor = list_json(ctx, "--label", label, "--limit", "2")
    R.expect(got == newest[:2], f"list --label --limit 2: expected {newest[:2]}, got {got}")
    R.expect(got is None or (isinstance(cursor, int) and not isinstance(cursor, bool)),
             f"list --label --limit 2: expected a next_cursor, got {cursor!r}")
    if isinstance(cursor, int):
        got2, cursor2 = list_json(ctx, "--label", label, "--cursor", str(cursor))
        R.expect(got2 == newest[2:], f"list --label --cursor {cursor}: expected {newest[2:]}, got {got2}")
        R.expect(got2 is None or cursor2 is None,
                 f"list --label --cursor {cursor}: expected next_cursor null, got {cursor2!r}")

    got, cursor = list_json(ctx, "--label", label, "--oldest-first")
    R.expect(got == ids, f"list --label --oldest-first: expected {ids}, got {got}")
    got, cursor = list_json(ctx, "--label", label, "--oldest-first", "--limit", "2")
    R.expect(got == ids[:2] and isinstance(cursor, int),
             f"list --label --oldest-first --limit 2: expected {ids[:2]} and a cursor, got {got}, {cursor!r}")
    if isinstance(cursor, int):
        got2, _ = list_json(ctx, "--label", label, "--oldest-first", "--cursor", str(cursor))
        R.expect(got2 == ids[2:], f"list --label --oldest-first --cursor {cursor}: expected {ids[2:]}, got {got2}")

    # Human output: the hint on stderr, the jobs on stdout.
    args = ("list", "--label", label, "--limit", "2", "--server", ctx.server())
    code, out, err = expect_exit(ctx, 0, *args)
    R.expect("springfit list --cursor" in err, f"{cli_desc(args)}: stderr lacks the hint "
                                               f"'springfit list --cursor': {err!r}")
    R.expect(all(str(j) in out for j in newest[:2]), f"{cli_desc(args)}: stdout lacks jobs {newest[:2]}: {short(out)}")
    args = ("list", "--label", label, "--server", ctx.server())
    code, out, err = expect_exit(ctx, 0, *args)
    R.expect("--cursor" not in err, f"{cli_desc(args)}: a hint although every job was shown: {err!r}")

    # trace --json: job.trace's answer, whole.
    with Conn(ctx.main.port) as c:
        job = wait_state(c, ids[0], FINAL_STATES, JOB_TIMEOUT)
    require(job["state"] == "succeeded", f"job {ids[0]} did not succeed: {short(job)}")
    args = ("trace", str(ids[0]), "--json", "--server", ctx.server())
    code, out, err = expect_exit(ctx, 0, *args)
    trace = parse_json_output(out, cli_desc(args)) if code == 0 else None
    if R.expect(isinstance(trace, dict) and set(trace) == {"rows", "next_after"},
                f"{cli_desc(args)}: expected {{\"rows\": [...], \"next_after\": null}}, got {short(out)}"):
        R.expect(trace["next_after"] is None, f"{cli_desc(args)}: next_after {trace['next_after']!r}")
        rows = trace["rows"]
        R.expect(isinstance(rows, list) and len(rows) >= 1 and
                 all(isinstance(r, dict) and "generation" in r for r in rows),
                 f"{cli_desc(args)}: rows of a finished job: {short(rows)}")
    # The table: E (the one error measure shown), not E squared under another name; on a fit
    # (the FEM plate: strategy continuous, whose rows are models after so many steps; a
    # search of the paper's scenes recovers them at E 0).
    args = ("submit", ctx.plate_path, "--server", ctx.server())
    code, out, err = expect_exit(ctx, 0, *args)
    require(code == 0 and out.strip().isdigit(), f"{cli_desc(args)}: expected a job id, got {out!r}")
    plate = int(out.strip())
    with Conn(ctx.main.port) as c:
        wait_state(c, plate, FINAL_STATES, JOB_TIMEOUT)
    code, out, err = expect_exit(ctx, 0, "trace", str(plate), "--json", "--server", ctx.server())
    rows = parse_json_output(out, "trace --json")["rows"] if code == 0 else []
    args = ("trace", str(plate), "--server", ctx.server())
    code, out, err = expect_exit(ctx, 0, *args)
    lines = out.splitlines()
    header = lines[0].split() if lines else []
    R.expect(header == ["model", "seconds", "steps", "E"], f"{cli_desc(args)}: header {header}")
    shown = [(int(l.split()[2]), float(l.split()[3])) for l in lines[1:]]
    want = [(r["evaluations"], r["best_normalized_error"] ** 0.5) for r in rows]
    R.expect(len(shown) == len(want) and all(w > 0 and s > 0 for s, w in want) and
             all(a == b and abs(e - w) <= 1e-5 * w for (a, e), (b, w) in zip(shown, want)),
             f"{cli_desc(args)}: steps and E {shown}, want {want}")


def test_idempotency(ctx):
    key = f"key-{ctx.nonce}"
    args = ("submit", ctx.iso_path, "--idempotency-key", key, "--server", ctx.server())
    code, out, err = expect_exit(ctx, 0, *args)
    require(code == 0 and out.strip().isdigit(), f"{cli_desc(args)}: expected a job id, got {out!r}")
    job_id = int(out.strip())

    args = ("submit", ctx.aniso_path, "--idempotency-key", key, "--server", ctx.server())
    code, out, err = expect_exit(ctx, 2, *args)
    R.expect(f"already used by job {job_id}" in err,
             f"{cli_desc(args)}: stderr lacks 'already used by job {job_id}': {err!r}")
    R.expect("a different scene" in err, f"{cli_desc(args)}: stderr lacks 'a different scene': {err!r}")
    R.expect(out == "", f"{cli_desc(args)}: unexpected stdout {out!r}")

    args = ("submit", ctx.iso_path, "--idempotency-key", key, "--server", ctx.server())
    code, out, err = expect_exit(ctx, 0, *args)
    R.expect(out.strip() == str(job_id), f"{cli_desc(args)} again: expected job id {job_id}, got {out!r}")
    R.expect("already submitted with this key" in err, f"{cli_desc(args)} again: stderr {err!r}")


def test_token_files(ctx):
    token_dir = os.path.join(ctx.tmp, "tokens")
    os.makedirs(token_dir)
    readable = os.path.join(token_dir, "readable.txt")
    with open(readable, "w") as f:
        f.write(TOKEN + "\n")
    os.chmod(readable, 0o644)
    code, err, port_written = run_refused_daemon(ctx, "token-0644", ["--workers", "1", "--token-file", readable])
    R.expect(code is not None and code != 0,
             f"springfitd --token-file (mode 0644): expected a non-zero exit within {REFUSE_TIMEOUT}s, got {code}")
    R.expect("readable by others" in err, f"springfitd --token-file (mode 0644): stderr {short(err)!r}")
    R.expect(not port_written, "springfitd --token-file (mode 0644) wrote a port file")

    directory = os.path.join(token_dir, "a-directory")
    os.makedirs(directory)
    os.chmod(directory, 0o700)
    code, err, port_written = run_refused_daemon(ctx, "token-dir", ["--workers", "1", "--token-file", directory])
    R.expect(code is not None and code != 0,
             f"springfitd --token-file DIRECTORY: expected a non-zero exit within {REFUSE_TIMEOUT}s, got {code}")
    R.expect("is a directory" in err, f"springfitd --token-file DIRECTORY: stderr {short(err)!r}")
    R.expect(not port_written, "springfitd --token-file DIRECTORY wrote a port file")

    private = os.path.join(token_dir, "private.txt")
    with open(private, "w") as f:
        f.write(TOKEN + "\n")
    os.chmod(private, 0o600)
    ctx.token_daemon = ctx.daemon("token", ["--token-file", private])
    with Conn(ctx.token_daemon.port) as c:
        info = c.result("server.info")
        R.expect(info.get("auth_required") is True, f"server.info of the token daemon: {short(info)}")
        r = c.result("session.auth", {"token": TOKEN})
        R.expect(r == {"authenticated": True}, f"session.auth with the right token: {short(r)}")


def test_wrong_tokens(ctx):
    require(ctx.token_daemon is not None and ctx.token_daemon.alive(), "no token daemon (see token files)")
    d = ctx.token_daemon
    with Conn(d.port) as c:
        for n in range(1, 5):
            resp = c.call("session.auth", {"token": WRONG_TOKEN})
            err = expect_error(resp, -32001, f"wrong token #{n}")
            R.expect(err.get("message") == "unauthorized: wrong token",
                     f"wrong token #{n}: expected the message 'unauthorized: wrong token', got {short(resp)}")
        resp = c.call("session.auth", {"token": WRONG_TOKEN})
        err = expect_error(resp, -32001, "wrong token #5")
        R.expect("connection is closed" in str(err.get("message")),
                 f"wrong token #5: expected a message saying the connection is closed, got {short(resp)}")
        R.expect(c.wait_closed(IO_TIMEOUT), "the server did not close the connection after the 5th wrong token")
    # The daemon goes on, for others and for the right token.
    with Conn(d.port) as c:
        r = c.result("session.auth", {"token": TOKEN})
        R.expect(r == {"authenticated": True}, f"session.auth after another connection's wrong tokens: {short(r)}")
        R.expect("jobs" in c.result("job.list"), "job.list after auth")
    # The log: one line for the connection's wrong tokens (the log is written as it happens;
    # polled briefly all the same). The log is the daemon's stdout and stderr together.
    deadline = time.monotonic() + 2
    while True:
        lines = [l for l in d.log_text().splitlines() if "wrong token (not logged again" in l]
        if len(lines) >= 1 or time.monotonic() > deadline:
            break
        time.sleep(0.05)
    R.expect(len(lines) == 1, f"the token daemon's log (stdout and stderr): expected exactly one line with "
                              f"'wrong token (not logged again', got {len(lines)}: {short(d.log_text(), 600)!r}")


def file_mode(path):
    return stat.S_IMODE(os.stat(path).st_mode)


def test_db_mode(ctx):
    d = ctx.daemon("dbmode")
    with Conn(d.port) as c:  # a write, so that the WAL exists if the store uses one
        sub = c.result("job.submit", {"scene": ctx.small_scene, "label": "dbmode"})
        wait_state(c, sub["job"]["job_id"], FINAL_STATES, JOB_TIMEOUT)
    require(os.path.exists(d.db), f"no database file {d.db} (files: {os.listdir(d.dir)})")
    seen = []
    for path in (d.db, d.db + "-wal", d.db + "-shm"):
        if os.path.exists(path):
            seen.append(os.path.basename(path))
            mode = file_mode(path)
            R.expect(mode == 0o600, f"{os.path.basename(path)} created by springfitd --db: mode {mode:04o}, "
                                    f"expected 0600")
    # The main daemon's database, created in a fresh directory too.
    for path in (ctx.main.db, ctx.main.db + "-wal", ctx.main.db + "-shm"):
        if os.path.exists(path):
            mode = file_mode(path)
            R.expect(mode == 0o600, f"the main daemon's {os.path.basename(path)}: mode {mode:04o}, expected 0600")
    R.expect(os.path.basename(d.db) in seen, f"no database file among {seen}")


def scene_text(scene, replacements):
    """The scene as JSON text, with each placeholder string replaced by a literal as written."""
    text = json.dumps(scene)
    for placeholder, literal in replacements.items():
        quoted = json.dumps(placeholder)
        require(text.count(quoted) == 1, f"placeholder {placeholder} not found once")
        text = text.replace(quoted, literal)
    return text


def labelled_jobs(conn, label):
    return conn.result("job.list", {"label": label})["jobs"]


def test_extreme_numbers(ctx):
    label = f"extreme-{ctx.nonce}"

    def with_stiffness():
        s = copy.deepcopy(ctx.small_scene)
        s["reference"]["stiffness"] = "@STIFFNESS@"
        return s

    node_scene = copy.deepcopy(ctx.small_scene)
    node_scene["nodes"][3][0] = "@X@"
    cases = [
        ("reference stiffness 1e-400", scene_text(with_stiffness(), {"@STIFFNESS@": "1e-400"}),
         "reference.stiffness", "reads as 0"),
        ("reference stiffness 1e308", scene_text(with_stiffness(), {"@STIFFNESS@": "1e308"}),
         "reference.stiffness", "outside [1e-100, 1e+100]"),
        ("nodes[3][0] = 1e308", scene_text(node_scene, {"@X@": "1e308"}), "nodes[3][0]", "beyond 1e+100"),
    ]
    with Conn(ctx.main.port) as c:
        newest_before = c.result("job.list", {"order": "newest", "limit": 1})["jobs"]
        for name, text, path, phrase in cases:
            resp = c.call_text("job.submit", '{"scene":%s,"label":%s}' % (text, json.dumps(label)))
            err = expect_error(resp, -32003, name)
            R.expect(error_data(err).get("path") == path,
                     f"{name}: expected data.path {path!r}, got {short(resp)}")
            R.expect(phrase in str(err.get("message")), f"{name}: the message lacks {phrase!r}: {short(resp)}")
        R.expect(labelled_jobs(c, label) == [], f"refused scenes were stored: {short(labelled_jobs(c, label))}")
        newest_after = c.result("job.list", {"order": "newest", "limit": 1})["jobs"]
        R.expect([j["job_id"] for j in newest_after] == [j["job_id"] for j in newest_before],
                 f"a job was created by a refused submission: newest before {short(newest_before)}, "
                 f"after {short(newest_after)}")


def test_search_bounds(ctx):
    label = f"bounds-{ctx.nonce}"
    scene = copy.deepcopy(ctx.small_scene)
    scene["search"] = dict(scene.get("search", {}), population=100000000)
    with Conn(ctx.main.port) as c:
        resp = c.call("job.submit", {"scene": scene, "label": label})
        err = expect_error(resp, -32004, "search.population 100000000")
        R.expect(error_data(err).get("limit") == "max_population",
                 f"search.population 100000000: expected data.limit max_population, got {short(resp)}")
        R.expect(labelled_jobs(c, label) == [], "a job refused for its population was stored")


def test_durable_cancel(ctx):
    """A running job cancelled (acknowledged) and the daemon killed at once: after the restart
    the job is cancelled, not run again (issue 15: 8 of 8 such cancels were lost)."""
    d = ctx.daemon("cancel-kill")
    with Conn(d.port) as c:
        scene = json.load(open(ctx.kidney_path))
        scene.setdefault("search", {}).update({"strategy": "paper", "max_generations": 100000})
        job_id = c.result("job.submit", {"scene": scene, "label": "cancel-kill"})["job"]["job_id"]
        job = wait_state(c, job_id, ("running",) + FINAL_STATES, 10)
        require(job["state"] == "running", f"job {job_id} does not run: {short(job)}")
        answer = c.result("job.cancel", {"job_id": job_id})
        R.expect(answer.get("state") in ("cancelling", "cancelled"), f"job.cancel: {short(answer)}")
    d.kill9()  # right after the acknowledgement: the job may not have stopped yet
    d.start()
    with Conn(d.port) as c:
        job = wait_state(c, job_id, FINAL_STATES, 20)
        R.expect(job["state"] == "cancelled",
                 f"job {job_id} cancelled before a kill -9 is {job['state']} after the restart")
        trace = c.result("job.trace", {"job_id": job_id})
        R.expect(len(trace.get("rows", [])) < 100000, "the cancelled job ran to its end")


def test_descriptor_limit(ctx):
    """--max-connections above what the descriptor limit allows: refused at start with the
    numbers and the fix; raised to what is needed where the hard limit allows."""
    hard = 200
    code, text, port_written = run_refused_daemon(
        ctx, "fd-refused", ["--max-connections", "1000"],
        setup=lambda: resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard)))
    R.expect(code not in (0, None), f"--max-connections 1000 under a limit of {hard}: exit {code}")
    R.expect("--max-connections 1000 needs 1064 file descriptors, above this process's limit of 200" in text,
             f"descriptor limit message: {short(text, 500)}")
    R.expect(not port_written, "a refused daemon wrote its port file")

    # Soft limit 100, hard 200: 100 connections need 164, which the hard limit allows.
    raised = Daemon(ctx.springfitd, ctx.tmp, "fd-raised", ["--max-connections", "100"],
                    setup=lambda: resource.setrlimit(resource.RLIMIT_NOFILE, (100, hard)))
    ctx.daemons.append(raised)
    raised.start()
    soft, _ = resource.prlimit(raised.proc.pid, resource.RLIMIT_NOFILE)
    R.expect(soft >= 164, f"the soft descriptor limit was not raised: {soft}")
    raised.stop()


def test_emfile_backoff(ctx):
    """Out of descriptors while connections keep coming: the accept loop waits and logs once a
    second (it logged 800k lines in 4 s), the daemon stays up, and serves again once
    descriptors are free."""
    d = ctx.daemon("emfile")
    open_fds = len(os.listdir(f"/proc/{d.proc.pid}/fd"))
    _, hard = resource.prlimit(d.proc.pid, resource.RLIMIT_NOFILE)
    resource.prlimit(d.proc.pid, resource.RLIMIT_NOFILE, (open_fds + 4, hard))
    held = []
    try:
        for _ in range(30):
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            s.settimeout(IO_TIMEOUT)
            try:
                s.connect(("127.0.0.1", d.port))  # completes in the kernel's backlog
            except OSError:
                s.close()
                break
            held.append(s)
        time.sleep(2.5)
        R.expect(d.alive(), "the daemon died out of descriptors")
        log = d.log_text()
        lines = [l for l in log.splitlines() if "accept:" in l]
        R.expect(1 <= len(lines) <= 5, f"{len(lines)} accept warnings in 2.5 s: {short(lines[:3])}")
    finally:
        for s in held:
            s.close()
        resource.prlimit(d.proc.pid, resource.RLIMIT_NOFILE, (hard, hard))
    with Conn(d.port) as c:
        info = c.result("server.info")
        R.expect(info.get("name") == "springfitd", f"server.info after descriptors came back: {short(info)}")


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


def test_failing_writes(ctx):
    """The database's writes failing (a file size limit of 1 byte: every write(2) fails with
    EFBIG, a real I/O error as a failing disk gives): submissions are answered -32007 saying
    so, never 'database disk image is malformed' (after one I/O error every answer said that,
    the file intact); reads still answer; the stored job stays intact; once writes succeed
    again the daemon takes submissions by itself (a new connection), without a restart."""
    d = Daemon(ctx.springfitd, ctx.tmp, "failing-writes", [],
               setup=lambda: signal.signal(signal.SIGXFSZ, signal.SIG_IGN))
    ctx.daemons.append(d)
    d.start()
    with Conn(d.port) as c:
        first = c.result("job.submit", {"scene": ctx.small_scene, "label": "before"})["job"]["job_id"]
        require(wait_state(c, first, FINAL_STATES, 30)["state"] == "succeeded", f"job {first} did not succeed")
        result_before = c.result("job.result", {"job_id": first})
        _, hard = resource.prlimit(d.proc.pid, resource.RLIMIT_FSIZE)
        resource.prlimit(d.proc.pid, resource.RLIMIT_FSIZE, (1, hard))
        try:
            for attempt in (1, 2):
                resp = c.call("job.submit", {"scene": ctx.small_scene, "label": f"during-{attempt}"})
                err = resp.get("error") or {}
                message = err.get("message", "")
                R.expect(err.get("code") == -32007 and "cannot be read or written" in message,
                         f"submission {attempt} with failing writes: {short(resp)}")
                R.expect("malformed" not in message, f"submission {attempt}: {message}")
            info = c.result("server.info")
            R.expect(info.get("name") == "springfitd", f"server.info with failing writes: {short(info)}")
            job = c.result("job.get", {"job_id": first})
            R.expect(job.get("state") == "succeeded", f"job {first} with failing writes: {short(job)}")
        finally:
            resource.prlimit(d.proc.pid, resource.RLIMIT_FSIZE, (hard, hard))
        created = c.result("job.submit", {"scene": ctx.small_scene, "label": "after"})
        R.expect(created.get("created") is True, f"submission after writes came back: {short(created)}")
        after = created["job"]["job_id"]
        R.expect(wait_state(c, after, FINAL_STATES, 30)["state"] == "succeeded", f"job {after} did not succeed")
        R.expect(c.result("job.result", {"job_id": first}) == result_before,
                 f"job {first}'s result changed across the failing writes")
        listed = [j["label"] for j in c.result("job.list", {})["jobs"]]
        R.expect(sorted(listed) == ["after", "before"], f"jobs after the failing writes: {listed}")

        # A running job whose progress writes fail for a while: it is neither failed nor lost,
        # and ends as it would have (its trace whole) once writes succeed again.
        scene = json.load(open(ctx.kidney_path))
        scene.setdefault("search", {}).update({"strategy": "paper", "max_seconds": 4})
        running = c.result("job.submit", {"scene": scene, "label": "running"})["job"]["job_id"]
        job = wait_state(c, running, ("running",) + FINAL_STATES, 10)
        require(job["state"] == "running", f"job {running} does not run: {short(job)}")
        time.sleep(1.0)
        resource.prlimit(d.proc.pid, resource.RLIMIT_FSIZE, (1, hard))
        try:
            time.sleep(2.0)
            job = c.result("job.get", {"job_id": running})
            R.expect(job["state"] in ("running", "queued"),
                     f"job {running} while its writes fail: {short(job)}")
        finally:
            resource.prlimit(d.proc.pid, resource.RLIMIT_FSIZE, (hard, hard))
        job = wait_state(c, running, FINAL_STATES, 60)
        R.expect(job["state"] == "succeeded", f"job {running} after its writes failed: {short(job)}")
        rows = c.result("job.trace", {"job_id": running, "limit": 10000})["rows"]
        generations = [r["generation"] for r in rows]
        R.expect(generations == list(range(len(generations))) and len(generations) > 1,
                 f"job {running}'s trace has holes: {short(generations)}")
    R.expect(d.alive(), "the daemon died of failing writes")
    R.expect("a new writing connection after an I/O error" in d.log_text(),
             f"no reopening in the log: {short(d.log_text()[-800:], 800)}")


def test_damaged_row(ctx):
    """A queued job whose row was damaged while the daemon was stopped (its progress column not
    JSON): the daemon starts all the same (it exited at start, issue 48), quarantines the job
    with one line in its log, runs the job queued behind it, and lists both, the damaged one
    apart as quarantined; reading it answers -32008 with the same incident every time."""
    d = ctx.daemon("damaged-row", ["--jobs", "1"])
    with Conn(d.port) as c:
        scene = json.load(open(ctx.kidney_path))
        scene.setdefault("search", {}).update({"strategy": "paper", "max_generations": 1000000})
        blocker = c.result("job.submit", {"scene": scene, "label": "blocker", "priority": 10})["job"]["job_id"]
        job = wait_state(c, blocker, ("running",) + FINAL_STATES, 10)
        require(job["state"] == "running", f"job {blocker} does not run: {short(job)}")
        damaged = c.result("job.submit", {"scene": ctx.small_scene, "label": "damaged", "priority": 5})["job"]["job_id"]
        good = c.result("job.submit", {"scene": ctx.small_scene, "label": "good"})["job"]["job_id"]
    require(d.stop(), "the daemon did not stop")
    db = sqlite3.connect(d.db)
    db.execute("UPDATE jobs SET progress = '{not json' WHERE id = ?", (damaged,))
    db.commit()
    db.close()
    d.start()
    with Conn(d.port) as c:
        c.result("job.cancel", {"job_id": blocker})
        job = wait_state(c, good, FINAL_STATES, 30)
        R.expect(job["state"] == "succeeded", f"the job behind the damaged one: {short(job)}")
        listed = c.result("job.list", {})
        R.expect([j["job_id"] for j in listed["jobs"]] == [blocker, good], f"job.list: {short(listed)}")
        quarantined = listed.get("quarantined") or [{}]
        R.expect(len(quarantined) == 1 and quarantined[0].get("job_id") == damaged
                 and quarantined[0].get("state") == "quarantined"
                 and "progress column" in quarantined[0].get("reason", ""),
                 f"job.list's quarantined: {short(listed)}")
        for read in (1, 2):
            err = expect_error(c.call("job.get", {"job_id": damaged}), -32008, f"job.get {read} of the damaged job")
            R.expect(error_data(err).get("incident") == quarantined[0].get("incident"),
                     f"job.get {read}: the incident is not the quarantine's: {short(err)}")
    R.expect(d.alive(), f"the daemon died: {short(d.log_text()[-800:], 800)}")
    lines = [l for l in d.log_text().splitlines() if f"job {damaged} quarantined" in l]
    R.expect(len(lines) == 1, f"the quarantine's lines in the log: {lines}")


def main(argv):
    groups = [
        ("setup", test_setup, True),
        ("client timeout", test_client_timeout, False),
        ("submit --wait --json", test_submit_wait, False),
        ("submit --watch: notices and phases", test_submit_watch_phases, False),
        ("watch interrupted", test_watch_interrupt, False),
        ("list and trace", test_list, False),
        ("idempotency key", test_idempotency, False),
        ("token files", test_token_files, False),
        ("wrong tokens", test_wrong_tokens, False),
        ("database mode", test_db_mode, False),
        ("extreme numbers", test_extreme_numbers, False),
        ("search bounds", test_search_bounds, False),
        ("preparation threads", test_preparation_threads, False),
        ("preparing state", test_preparing_state, False),
        ("durable cancel", test_durable_cancel, False),
        ("damaged row", test_damaged_row, False),
        ("failing writes", test_failing_writes, False),
        ("descriptor limit", test_descriptor_limit, False),
        ("EMFILE back-off", test_emfile_backoff, False),
    ]
    return run_suite(argv, __doc__.strip().split("\n\n")[1], Context, groups,
                     lambda daemon: daemon.log_text())


if __name__ == "__main__":
    sys.exit(main(sys.argv))
