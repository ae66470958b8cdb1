#!/usr/bin/env python3
"""Control within a second (bench/RESULTS.md, "Control"): for each scene, how long
`springfit run` takes to print its first progress line, and how long it takes to exit after
SIGINT sent mid-run; and for the daemon, how long a running job takes to end after job.cancel.

usage: bench/control_latency.py BUILD_DIR SCENE... [--after SECONDS]

Times are wall seconds on this machine, one run each. The first progress line (a generation's
line, or a beat of the analysis or direct phase) counts from the start of the process (scene
reading and the reference's preparation included)."""
import argparse
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time


def first_line_and_interrupt(springfit, scene, after):
    start = time.monotonic()
    proc = subprocess.Popen([springfit, "run", scene, "--threads", "2", "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    os.set_blocking(proc.stderr.fileno(), False)
    first = None
    buf = b""
    while time.monotonic() - start < after:
        if proc.poll() is not None:
            break
        chunk = proc.stderr.read() or b""
        buf += chunk
        if first is None and re.search(rb"generation \d+/|[a-z]+ phase ", buf):
            first = time.monotonic() - start
        time.sleep(0.005)
    if proc.poll() is not None:
        return first, None, "finished before the interrupt"
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    proc.wait(timeout=600)
    stop = time.monotonic() - sent
    result = json.loads(proc.stdout.read())
    return first, stop, result["stop"]


def daemon_cancel(build, scene, after):
    with tempfile.TemporaryDirectory() as tmp:
        port_file = os.path.join(tmp, "port")
        daemon = subprocess.Popen([os.path.join(build, "server/springfitd"), "--listen", "127.0.0.1:0",
                                   "--db", os.path.join(tmp, "jobs.db"), "--port-file", port_file,
                                   "--workers", "2"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            for _ in range(200):
                if os.path.exists(port_file) and open(port_file).read().strip():
                    break
                time.sleep(0.05)
            env = dict(os.environ, SPRINGFIT_SERVER="127.0.0.1:" + open(port_file).read().strip())
            sf = os.path.join(build, "client/springfit")
            job = subprocess.run([sf, "submit", scene], env=env, capture_output=True, text=True,
                                 check=True).stdout.strip()
            time.sleep(after)
            sent = time.monotonic()
            if subprocess.run([sf, "cancel", job], env=env, capture_output=True).returncode == 9:
                return None  # the job had finished already
            subprocess.run([sf, "watch", job, "-q"], env=env, capture_output=True)
            return time.monotonic() - sent
        finally:
            daemon.send_signal(signal.SIGTERM)
            daemon.wait(timeout=60)


def fmt(value):
    return "-" if value is None else "%.3f" % value


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("build")
    parser.add_argument("scenes", nargs="+")
    parser.add_argument("--after", type=float, default=5.0, help="seconds before the interrupt/cancel")
    args = parser.parse_args()
    springfit = os.path.join(args.build, "client/springfit")
    print("| scene | first progress line s | exit after SIGINT s | stop | job.cancel to end s |")
    print("|---|---:|---:|---|---:|")
    for scene in args.scenes:
        first, stop, reason = first_line_and_interrupt(springfit, scene, args.after)
        cancel = daemon_cancel(args.build, scene, args.after)
        print("| %s | %s | %s | %s | %s |" % (os.path.basename(scene), fmt(first), fmt(stop), reason, fmt(cancel)))
        sys.stdout.flush()


if __name__ == "__main__":
    main()
