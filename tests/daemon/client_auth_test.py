#!/usr/bin/env python3
"""End-to-end test of springfitd's token files and of wrong tokens.

Usage: client_auth_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts daemons on 127.0.0.1 with a free port in a temporary directory and checks: token files
readable by others or directories refused at start (no port file written), a private token
file taken, and wrong tokens on one connection (the fifth closes it, one log line, the daemon
goes on for the right token). Python 3 standard library only (the shared part:
client_support.py).

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import os
import sys
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree for harness.py
from harness import IO_TIMEOUT, Conn, R, require, short  # noqa: E402
from client_support import (REFUSE_TIMEOUT, TOKEN, WRONG_TOKEN, expect_error,  # noqa: E402
                            run_groups, run_refused_daemon)


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


if __name__ == "__main__":
    sys.exit(run_groups(sys.argv, __doc__, [
        ("token files", test_token_files, False),
        ("wrong tokens", test_wrong_tokens, False),
    ]))
