#!/usr/bin/env python3
"""Control within a second (bench/RESULTS.md, "Control"): for each scene, how long
`springfit run` takes to print its first progress line, and how long it takes to exit after
SIGINT sent mid-run; and for the daemon, how long a running job takes to end after job.cancel.

usage: bench/control_latency.py BUILD_DIR SCENE... [--after SECONDS] [--preparing]

A SCENE named grid:N is an N x N grid MSS (tests/daemon/harness.py grid_scene: N^2 nodes,
edges and both diagonals of every cell, pulled on one side), written to a temporary file.

--preparing: instead, for the daemon, how long a submission takes to end after job.cancel
sent `--after` seconds into its preparation (the state `preparing`: the reference's
equilibria of a large scene).

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


def started_daemon(build, tmp):
    """springfitd on a port of its own, its database in tmp; (process, environment)."""
    port_file = os.path.join(tmp, "port")
    daemon = subprocess.Popen([os.path.join(build, "server/springfitd"), "--listen", "127.0.0.1:0",
                               "--db", os.path.join(tmp, "jobs.db"), "--port-file", port_file,
                               "--workers", "2"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    for _ in range(200):
        if os.path.exists(port_file) and open(port_file).read().strip():
            break
        time.sleep(0.05)
    return daemon, dict(os.environ, SPRINGFIT_SERVER="127.0.0.1:" + open(port_file).read().strip())


def preparing_cancel(build, scene, after):
    """(seconds from job.cancel to the submission's end, its final stderr line), or None when
    the preparation ended first."""
    sf = os.path.join(build, "client/springfit")
    with tempfile.TemporaryDirectory() as tmp:
        daemon, env = started_daemon(build, tmp)
        try:
            submit = subprocess.Popen([sf, "submit", scene, "--timeout", "600"], env=env,
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            first = submit.stderr.readline()  # "job N preparing (...)", after a second
            match = re.match(r"job (\d+) preparing", first)
            if not match:
                submit.wait(timeout=600)
                return None
            time.sleep(max(0.0, after - 1.0))
            sent = time.monotonic()
            subprocess.run([sf, "cancel", match.group(1)], env=env, capture_output=True)
            _, err = submit.communicate(timeout=600)
            last = err.strip().splitlines()[-1]
            return (time.monotonic() - sent, last) if "cancelled while" in last else None
        finally:
            daemon.send_signal(signal.SIGTERM)
            daemon.wait(timeout=60)


def daemon_cancel(build, scene, after):
    with tempfile.TemporaryDirectory() as tmp:
        daemon, env = started_daemon(build, tmp)
        try:
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


def scene_files(scenes, tmp):
    """The scene paths, grid:N ones written into tmp."""
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "daemon"))
    sys.dont_write_bytecode = True
    from harness import grid_scene
    paths = []
    for scene in scenes:
        if scene.startswith("grid:"):
            n = int(scene[5:])
            path = os.path.join(tmp, f"grid-{n}x{n}.json")
            with open(path, "w") as f:
                json.dump(grid_scene(n, f"grid-{n}x{n}"), f, separators=(",", ":"))
            scene = path
        paths.append(scene)
    return paths


def fmt(value):
    return "-" if value is None else "%.3f" % value


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("build")
    parser.add_argument("scenes", nargs="+")
    parser.add_argument("--after", type=float, default=5.0, help="seconds before the interrupt/cancel")
    parser.add_argument("--preparing", action="store_true",
                        help="cancel daemon submissions during their preparation")
    args = parser.parse_args()
    scenes_dir = tempfile.TemporaryDirectory()
    args.scenes = scene_files(args.scenes, scenes_dir.name)
    if args.preparing:
        print("| scene | job.cancel to the submission's end s | its last line |")
        print("|---|---:|---|")
        for scene in args.scenes:
            measured = preparing_cancel(args.build, scene, args.after)
            cancel, line = measured if measured else (None, "prepared before the cancel")
            print("| %s | %s | %s |" % (os.path.basename(scene), fmt(cancel), line))
            sys.stdout.flush()
        return
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
