#!/usr/bin/env python3
"""End-to-end test of the springfit client's job commands against springfitd.

Usage: client_jobs_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts springfitd on 127.0.0.1 with a free port in a temporary directory and checks: the
client's --timeout against a server that never answers, `submit --wait --json`, `submit
--watch` (the scene's notices and the phases), Ctrl-C on a watch (the job keeps running),
`list` paging and order, `trace --json` and its table, and idempotency keys reused for another
scene. Python 3 standard library only (the shared part: client_support.py).

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree for harness.py
from harness import Conn, R, require, short, wait_state  # noqa: E402
from client_support import (FINAL_STATES, JOB_TIMEOUT, cli_desc, expect_exit,  # noqa: E402
                            parse_json_output, run_cli, run_groups, test_setup)


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


if __name__ == "__main__":
    sys.exit(run_groups(sys.argv, __doc__, [
        ("setup", test_setup, True),
        ("client timeout", test_client_timeout, False),
        ("submit --wait --json", test_submit_wait, False),
        ("submit --watch: notices and phases", test_submit_watch_phases, False),
        ("watch interrupted", test_watch_interrupt, False),
        ("list and trace", test_list, False),
        ("idempotency key", test_idempotency, False),
    ]))
