#!/usr/bin/env python3
"""Outside-in test of springfitd's framing of JSON-RPC messages over TCP (proto/RPC.md).

Usage: protocol_framing_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts springfitd on 127.0.0.1 with a free port in a temporary directory and checks, against
the documented behaviour: one request per line, a request over several lines, several requests
in one send and back to back on one line, a request without its newline, and a request sent
byte by byte (answered once whole, in one line). Python 3 standard library only (the shared
part: protocol_support.py).

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import json
import socket
import sys
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree for harness.py
from harness import Conn, R, require, short  # noqa: E402
from protocol_support import run_groups, test_setup  # noqa: E402


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


if __name__ == "__main__":
    sys.exit(run_groups(sys.argv, __doc__, [
        ("setup", test_setup, True),
        ("framing", test_framing, False),
    ]))
