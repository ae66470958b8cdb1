#!/usr/bin/env python3
"""End-to-end test of springfitd's bounds: on what a submission holds and on descriptors.

Usage: client_limits_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts daemons on 127.0.0.1 with a free port in a temporary directory and checks: numbers
beyond the scene's bounds (-32003 naming the field, nothing stored), the search's population
bound (-32004), --max-connections above the descriptor limit (refused at start, or the limit
raised), and running out of descriptors (the accept loop backs off and logs once a second).
Python 3 standard library only (the shared part: client_support.py).

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import copy
import json
import os
import resource
import socket
import sys
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree for harness.py
from harness import IO_TIMEOUT, Conn, Daemon, R, error_data, require, short  # noqa: E402
from client_support import expect_error, run_groups, run_refused_daemon, test_setup  # noqa: E402


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


if __name__ == "__main__":
    sys.exit(run_groups(sys.argv, __doc__, [
        ("setup", test_setup, True),
        ("extreme numbers", test_extreme_numbers, False),
        ("search bounds", test_search_bounds, False),
        ("descriptor limit", test_descriptor_limit, False),
        ("EMFILE back-off", test_emfile_backoff, False),
    ]))
