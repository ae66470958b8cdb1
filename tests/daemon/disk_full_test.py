#!/usr/bin/env python3
"""A full disk under springfitd's SQLite database (issue 32 item 7), on a real tmpfs that
disk_full_test.sh mounts in a private mount namespace.

While jobs run and queue and a client watches one of them, a file fills the tmpfs: a
submission is refused with -32007 and the disk named, nothing acknowledged is lost, no job
fails. When the file is removed the daemon resumes by itself: some job moves within 5 s, every
job succeeds, and the watcher gets its job.finished, with no restart.

Usage: disk_full_test.py SPRINGFITD SPRINGFIT SOURCE_DIR TMPFS_DIR
"""
import json
import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness as h  # noqa: E402

R = h.R
JOBS = 6
RESUME_SECONDS = 5.0   # "within a few seconds of space returning"
FINISH_SECONDS = 120.0


def main():
    springfitd, springfit, source, root = sys.argv[1:5]
    free = os.statvfs(root)
    if free.f_blocks * free.f_frsize > 64 << 20:
        print(f"FAIL: {root} is not the small tmpfs this test fills ({free.f_blocks * free.f_frsize} bytes)")
        return 1
    scene = json.loads(subprocess.run([springfit, "example", "kidney-2d"], capture_output=True,
                                      text=True, check=True).stdout)
    scene["search"] = {"strategy": "paper", "max_generations": 60}
    daemon = h.Daemon(springfitd, root, "daemon").start()
    filler = os.path.join(root, "filler")
    try:
        conn = h.Conn(daemon.port)
        ids = [conn.result("job.submit", {"scene": scene, "seed": s})["job"]["job_id"] for s in range(JOBS)]
        watcher = h.Conn(daemon.port)
        watched = ids[-1]  # queued: it runs only after the disk has space again
        watcher.result("job.watch", {"job_id": watched})
        time.sleep(1.0)

        # Fill the disk.
        with open(filler, "wb") as f:
            try:
                while True:
                    f.write(b"\0" * 65536)
                    f.flush()
            except OSError as e:
                R.expect(e.errno == 28, f"filling the tmpfs: {e}")
        time.sleep(3.0)
        refused = conn.call("job.submit", {"scene": scene, "seed": 99})
        err = refused.get("error") or {}
        R.expect(err.get("code") == -32007 and "is full; nothing was written" in err.get("message", ""),
                 f"a submission on a full disk: {h.short(refused)}")

        def snapshot():
            out = []
            for i in ids:
                job = conn.result("job.get", {"job_id": i})
                out.append((job["state"], (job.get("progress") or {}).get("generation")))
            return out

        full = snapshot()
        R.expect(all(state in ("queued", "running") for state, _ in full)
                 and any(state == "queued" for state, _ in full),
                 f"jobs while the disk is full (some still queued): {full}")

        # Space returns: the daemon moves by itself.
        os.remove(filler)
        t0 = time.monotonic()
        moved = None
        states = full
        while time.monotonic() - t0 < FINISH_SECONDS:
            states = snapshot()
            # (A running job's generation may go on in memory while the store is stuck: what
            # counts is a queued job claimed, which takes a write.)
            if moved is None and any(before == "queued" and now != "queued"
                                     for (before, _), (now, _) in zip(full, states)):
                moved = time.monotonic() - t0
            if all(state in ("succeeded", "failed", "cancelled") for state, _ in states):
                break
            time.sleep(0.1)
        print(f"space returned: first move after {moved}s, all ended after "
              f"{time.monotonic() - t0:.1f}s: {states}")
        R.expect(moved is not None and moved <= RESUME_SECONDS,
                 f"no job moved within {RESUME_SECONDS}s of space returning (moved after {moved}s)")
        R.expect(all(state == "succeeded" for state, _ in states), f"every job succeeds: {states}")
        R.expect(len(conn.result("job.list", {})["jobs"]) == JOBS,
                 "the refused submission created no job")
        finished = None
        deadline = time.monotonic() + 10
        while finished is None and time.monotonic() < deadline:
            msg = watcher.read(timeout=max(0.1, deadline - time.monotonic()), what="job.finished")
            if msg.get("method") == "job.finished" and msg["params"].get("job_id") == watched:
                finished = msg["params"]
        R.expect(finished is not None and finished.get("state") == "succeeded",
                 f"the watcher's job.finished: {h.short(finished)}")
        R.expect(daemon.alive(), "the daemon runs on")
    except h.Abort as e:
        R.fail(f"aborted: {e}")
    finally:
        if os.path.exists(filler):
            os.remove(filler)
        daemon.stop()
    if R.failures:
        print(f"disk_full: {len(R.failures)} failed\n{h.short(daemon.log_text(), 2000)}")
        return 1
    print("disk_full: all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
