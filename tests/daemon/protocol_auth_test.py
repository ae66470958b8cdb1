#!/usr/bin/env python3
"""Outside-in test of springfitd's authentication, and of the springfit client's exit codes.

Usage: protocol_auth_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts daemons on 127.0.0.1 with a free port in temporary directories and checks, against the
documented behaviour: authentication (-32001 before session.auth and after a wrong token, a
bound on messages before it, one connection's authentication not another's, batches checked
member by member, a public address refused without a token) and the exit codes of the
springfit client (against the daemon, a closed port and the token daemon). Python 3 standard
library only (the shared part: protocol_support.py).

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import os
import subprocess
import sys

sys.dont_write_bytecode = True  # no __pycache__ in the source tree for harness.py
from harness import IO_TIMEOUT, Conn, R, error_data, require, short  # noqa: E402
from protocol_support import expect_error, run_groups, test_setup  # noqa: E402

# IO_TIMEOUT (5 s), START_TIMEOUT (10 s) and STOP_TIMEOUT (15 s) are harness.py's.
CLI_TIMEOUT = 20.0        # for one springfit invocation

TOKEN = "0123456789abcdefABCDEF0123456789"        # 32 characters
WRONG_TOKEN = "0123456789abcdefABCDEF012345678X"  # same length, last character differs


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


if __name__ == "__main__":
    sys.exit(run_groups(sys.argv, __doc__, [
        ("setup", test_setup, True),
        ("auth", test_auth, False),
        ("cli", test_cli, False),
    ]))
