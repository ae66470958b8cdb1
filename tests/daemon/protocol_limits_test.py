#!/usr/bin/env python3
"""Outside-in test of springfitd's limits on messages and connections (proto/RPC.md).

Usage: protocol_limits_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts daemons on 127.0.0.1 with a free port in temporary directories and checks, against the
documented behaviour: an over-size message (-32004, the connection closed, others going on),
the connection limit (-32005 to the one too many, a free slot taken again), and a message
trickled a byte at a time or left half sent (cut off at --message-seconds). Python 3 standard
library only (the shared part: protocol_support.py).

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import json
import socket
import sys
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree for harness.py
from harness import IO_TIMEOUT, Conn, R, error_data, require, short  # noqa: E402
from protocol_support import expect_error, run_groups  # noqa: E402


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


if __name__ == "__main__":
    sys.exit(run_groups(sys.argv, __doc__, [
        ("over-size", test_oversize, False),
        ("connection limit", test_connection_limit, False),
        ("trickle", test_trickle, False),
    ]))
