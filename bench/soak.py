#!/usr/bin/env python3
"""The daemon soak (issue 48): springfitd under load and a seeded chaos schedule, then the
invariants checked.

    python3 bench/soak.py [--store sqlite|postgres] [--daemons N] [--clients M] [--seconds S]
                          [--seed K] [--json OUT] [--springfitd PATH] [--springfit PATH]

N daemons (SQLite: one, its database on a tmpfs in a private mount namespace; PostgreSQL:
several sharing one private server that tests/server/with_postgres.sh starts, unless
SPRINGFIT_TEST_PG_DIR names one already) serve M client threads that submit jobs (with
idempotency keys, retried through any daemon until acknowledged), watch, poll, cancel and
query them (job.get, job.list, job.result, job.trace, job.scene, server.info) for S seconds,
while a chaos schedule drawn from the seed injects, in rounds that each hold every kind once:

  kill         kill -9 of a daemon at a random point, restarted 0.2-3 s later
  freeze       SIGSTOP of a daemon for its lease plus 0.5-2.5 s, then SIGCONT
  pg-restart   PostgreSQL stopped (fast or immediate) and started again at once   (postgres)
  pg-stop      PostgreSQL stopped for 2-8 s, past the lease, then started          (postgres)
  disk-full    the tmpfs under the database filled (to ENOSPC, or to within a few
               hundred KB that the daemon's own writes then fill) for 2-6 s, then freed
               by deleting the filler or by growing the filesystem                  (sqlite)
  damage       a queued job's row damaged behind the daemons' back (progress not JSON,
               a progress row with a wrong field, or an unknown state), as the store
               suite and client_store_test.py's "damaged row" do
  disconnect   a client gone mid-message: half a request then close, a reset (RST) in the
               middle of one, a submit closed before its answer, a watch abandoned
  slowloris    8 connections sending a request a byte at a time, or half of one and then
               nothing; each must be cut at --message-seconds (5 s here)

Faults overlap (a disk fills while a daemon is frozen, PostgreSQL stops while one is dead).
When the S seconds are over, every fault is healed, the clients stop submitting, and the
soak waits (at most --drain-seconds) for every job to end. Then it checks:

  lost         every acknowledged job is stored and ended: succeeded, failed or cancelled, or
               quarantined, and quarantined only if the schedule damaged its row
  once         every terminal state a client saw is the job's final one, no job was seen
               unfinished after it ended, no job was logged as finished twice, one job per
               idempotency key
  results      every succeeded job's result (model, springs, stiffness, E, ...: everything
               but wall times, thread counts and cache hits) and its whole trace equal a
               local `springfit run` of the same scene and seed; a result read twice is
               the same
  two places   no job ran in two places at once. From the store's lease history (table
               leases, every claim in the store's clock): each claim began after the one
               before had ended or expired, epochs rising, and every succeeded job has its
               claims there. Beside it, the current lease sampled twice a second (one owner
               per epoch, epochs never going back), and each run of a job rebuilt from the
               daemons' logs (`job N running` to its end): a run that started while another
               was still going must find the older run ending without a write (lease lost,
               interrupted, killed), never finishing the job; no run starts after the job
               ended
  crashed      no daemon exited but those the schedule killed (a start refused while the
               store is unavailable is counted apart), each exits 0 on the final SIGTERM,
               and no log holds a sanitizer report, `terminate called` or an internal error
  memory       the peak RSS of every daemon (sampled from /proc twice a second) within
               --max-rss-mb
  wedged       every daemon that is running and not frozen answers server.info within 10 s
               (its latency is reported)
  damage       every damaged row quarantined, and nothing else
  cancel       no job cancelled that no client asked to cancel; no job failed

It prints two tables (faults injected by kind; jobs, lost, duplicated, crashed, peak memory
and the rest) and PASS or FAIL per invariant, with the evidence of each failure; exit
status 0 when every invariant holds. --json OUT writes the schedule, the figures and the
failures. The temporary directory (logs, database) is removed at the end unless --keep.

The CI test (tests/daemon/soak_test.sh) runs a short schedule on each store; bench/RESULTS.md,
"Daemon soak", has the long runs. Python 3 standard library only.
"""

import argparse
import collections
import ctypes
import datetime
import hashlib
import heapq
import json
import math
import os
import queue
import random
import re
import shutil
import signal
import socket
import sqlite3
import subprocess
import sys
import tempfile
import threading
import time
import traceback

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# The daemon tests' connection (one line reader for the tests and the soak).
sys.path.insert(0, os.path.join(ROOT, "tests", "daemon"))
from harness import Conn  # noqa: E402
WITH_POSTGRES = os.path.join(ROOT, "tests", "server", "with_postgres.sh")
TERMINAL = ("succeeded", "failed", "cancelled")
# Not reproducible by design (proto/RPC.md, "Durability"): wall times, the fitness cache's
# hits and the thread count; at any depth of a result (direct.seconds, continuous.model_seconds).
IGNORED = {"wall_seconds", "seconds", "model_seconds", "cache_hits", "threads"}
CALL_TIMEOUT = 5.0        # one RPC: connect, send, answer
WEDGED_SECONDS = 10.0     # a running, unfrozen daemon that does not answer server.info within it
START_TIMEOUT = 30.0      # a daemon's port file
STOP_TIMEOUT = 20.0       # a daemon's exit after SIGTERM (--shutdown-seconds is 10)
MESSAGE_SECONDS = 5.0     # the daemons' --message-seconds: what a slow-loris is cut at
SLOW_PROBE_SECONDS = 1.0  # a server.info answer slower than this is listed with its context
SLOW_PROBE_CONTEXT = 10.0  # seconds of the fault schedule before a slow probe, listed with it
LORIS_CONNECTIONS = 8

# Small, fast jobs (bench/RESULTS.md: 0.1-2.5 s each on one core), with a weight each. The
# longer ones (aniso, plate-hybrid, kidney) run long enough for kills and freezes to land
# after a checkpoint (--checkpoint-seconds 0.5) and resume from it.
JOB_KINDS = {
    "iso": ("paper-iso-5x5", {"strategy": "paper", "max_generations": 40}, 3),
    "aniso": ("paper-aniso-5x5", {"strategy": "paper", "max_generations": 300}, 2),
    "plate": ("fem-plate-5x5", {}, 2),
    "plate-hybrid": ("fem-plate-5x5", {"strategy": "hybrid", "max_generations": 30}, 1),
    "stiff": ("stiff-2d", {"strategy": "direct"}, 2),
    "kidney": ("kidney-2d", {"strategy": "paper", "max_generations": 10}, 1),
}
FAULTS = {
    "sqlite": ["kill", "freeze", "disk-full", "damage", "disconnect", "slowloris"],
    "postgres": ["kill", "freeze", "pg-restart", "pg-stop", "damage", "disconnect", "slowloris"],
}
DAMAGE = {  # a queued row made unreadable, as tests/server/store_quarantine_test.cpp does
    "progress-not-json": "progress = '{not json'",
    "progress-bad-field": "progress = '{\"generation\": \"x\"'",
    "state-unknown": "state = 'bogus'",
}


def now():
    return time.time()


def log_time(stamp):
    """A springfitd log line's time stamp (local time, %Y-%m-%dT%H:%M:%S.%e) in Unix seconds."""
    return datetime.datetime.strptime(stamp, "%Y-%m-%dT%H:%M:%S.%f").timestamp()


def short(text, n=300):
    text = text if isinstance(text, str) else repr(text)
    return text if len(text) <= n else text[:n] + "..."


def strip(value):
    """A result or trace row without the members no two runs share (IGNORED, at any depth)."""
    if isinstance(value, dict):
        return {k: strip(v) for k, v in value.items() if k not in IGNORED}
    if isinstance(value, list):
        return [strip(v) for v in value]
    return value


def differences(a, b, path="", out=None, limit=5):
    """The first paths where two stripped JSON values differ."""
    out = [] if out is None else out
    if len(out) >= limit:
        return out
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            differences(a.get(k, "<absent>"), b.get(k, "<absent>"), f"{path}.{k}", out, limit)
    elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            differences(x, y, f"{path}[{i}]", out, limit)
    elif a != b or type(a) is not type(b):
        out.append(f"{path or '.'}: {short(json.dumps(a), 80)} != {short(json.dumps(b), 80)}")
    return out


def percentile(values, p):
    if not values:
        return None
    ordered = sorted(values)
    return ordered[max(0, math.ceil(p / 100 * len(ordered)) - 1)]


# --------------------------------------------------------------------------------------------
# JSON-RPC, one connection per call


class Down(Exception):
    """The daemon cannot be reached, closed the connection, or did not answer in time."""


def rpc(port, method, params=None, timeout=CALL_TIMEOUT):
    """(result, error), one of them None; raises Down."""
    if port is None:
        raise Down("not running")
    deadline = time.monotonic() + timeout
    try:
        with Conn(port, timeout=timeout) as conn:
            message = {"jsonrpc": "2.0", "id": 1, "method": method}
            if params is not None:
                message["params"] = params
            conn.send(json.dumps(message).encode() + b"\n")
            while True:
                line = conn.read_raw_line(max(deadline - time.monotonic(), 0.0))
                if line is None:
                    raise Down("no answer" if not conn.eof else "closed")
                answer = json.loads(line)
                if answer.get("id") == 1:
                    return answer.get("result"), answer.get("error")
                # (job.preparing notices before a slow submission's answer)
    except (OSError, ValueError) as e:
        raise Down(f"{type(e).__name__}: {e}") from None


# --------------------------------------------------------------------------------------------
# Processes: every daemon is started by one long-lived thread with PR_SET_PDEATHSIG, so that
# nothing outlives the soak, even a soak killed with SIGKILL.


def _die_with_parent():
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except OSError:
        pass


class Spawner(threading.Thread):
    def __init__(self):
        super().__init__(name="spawner", daemon=True)
        self.requests = queue.Queue()

    def run(self):
        while True:
            request = self.requests.get()
            if request is None:
                return
            args, kwargs, box, done = request
            try:
                box.append(subprocess.Popen(args, preexec_fn=_die_with_parent, **kwargs))
            except Exception as e:  # noqa: BLE001 - handed to the caller
                box.append(e)
            done.set()

    def popen(self, args, **kwargs):
        box, done = [], threading.Event()
        self.requests.put((args, kwargs, box, done))
        done.wait()
        if isinstance(box[0], Exception):
            raise box[0]
        return box[0]

    def stop(self):
        self.requests.put(None)


class Instance:
    """One process of a daemon slot (restarts make new instances, named dSLOT.N)."""

    def __init__(self, name, log_path):
        self.name = name
        self.log_path = log_path
        self.proc = None
        self.launched = now()
        self.up_at = None
        self.ended = None
        self.end = None            # killed | crashed | refused | stopped | stop-failed
        self.returncode = None
        self.expected_exit = False
        self.peak_rss = 0

    def log(self):
        try:
            with open(self.log_path, "rb") as f:
                return f.read().decode("utf-8", "replace")
        except OSError:
            return ""


class Slot:
    """A daemon slot: at most one running instance at a time, restarted after kills."""

    def __init__(self, soak, index):
        self.soak = soak
        self.index = index
        self.lock = threading.RLock()
        self.incarnation = 0
        self.inst = None
        self.port = None
        self.state = "down"        # starting | up | frozen | down
        self.healthy_from = math.inf
        self.unhealthy = []        # [t0, t1] windows: frozen, dead, starting (for judging)
        self.unhealthy_since = now()
        self.instances = []

    def _mark_unhealthy(self):
        if self.unhealthy_since is None:
            self.unhealthy_since = now()

    def _mark_healthy(self, at):
        if self.unhealthy_since is not None:
            self.unhealthy.append((self.unhealthy_since, at))
            self.unhealthy_since = None
        self.healthy_from = at

    def healthy_during(self, t0, t1):
        with self.lock:
            if self.unhealthy_since is not None and self.unhealthy_since <= t1:
                return False
            return not any(a <= t1 and b >= t0 for a, b in self.unhealthy)

    def launch(self):
        s = self.soak
        with self.lock:
            if self.state in ("starting", "up", "frozen"):
                return
            self.incarnation += 1
            name = f"d{self.index}.{self.incarnation}"
            inst = Instance(name, os.path.join(s.logdir, name + ".log"))
            port_file = os.path.join(s.logdir, name + ".port")
            cmd = [s.args.springfitd, "--listen", "127.0.0.1:0", "--port-file", port_file,
                   "--name", name, "--workers", str(s.args.daemon_workers),
                   "--jobs", str(s.args.daemon_jobs), "--lease-seconds", str(s.args.lease_seconds),
                   "--checkpoint-seconds", "0.5", "--message-seconds", str(MESSAGE_SECONDS),
                   "--idle-seconds", "60", "--log-level", "info"] + s.store_args
            with open(inst.log_path, "ab") as log:
                inst.proc = s.spawner.popen(cmd, stdin=subprocess.DEVNULL, stdout=log,
                                            stderr=subprocess.STDOUT)
            inst.port_file = port_file
            self.inst = inst
            self.instances.append(inst)
            self.state = "starting"
            self.port = None
            self._mark_unhealthy()

    def poll(self):
        """The monitor's look at the slot: a start completed or failed, an unplanned exit."""
        s = self.soak
        with self.lock:
            inst = self.inst
            if inst is None or self.state == "down":
                return
            code = inst.proc.poll()
            if self.state == "starting":
                if code is not None:
                    inst.ended, inst.returncode = now(), code
                    # (A daemon cannot open a store that is down, or a database on a full
                    # disk, and says so; a few seconds' grace after the store is back.)
                    store_down = s.store_fault_active() or now() - s.store_fault_ended < 5.0
                    if code > 0 and store_down:
                        inst.end = "refused"
                        s.count("start refused (store unavailable)")
                    else:
                        inst.end = "crashed"
                        s.crash(inst, f"exited at start with {code}")
                    self.state = "down"
                    s.timeline.push(now() + 1.0, self.launch, "relaunch", recovery=True, retry=True)
                    return
                try:
                    with open(inst.port_file) as f:
                        text = f.read().strip()
                except OSError:
                    text = ""
                if text:
                    self.port = int(text)
                    self.state = "up"
                    inst.up_at = now()
                    self._mark_healthy(now() + 1.0)
                elif now() - inst.launched > START_TIMEOUT:
                    inst.expected_exit = True
                    inst.proc.kill()
                    inst.proc.wait(10)
                    inst.ended, inst.end, inst.returncode = now(), "crashed", inst.proc.returncode
                    s.crash(inst, f"no port file within {START_TIMEOUT:.0f} s of its start")
                    self.state = "down"
                    s.timeline.push(now() + 1.0, self.launch, "relaunch", recovery=True, retry=True)
                return
            if code is not None and not inst.expected_exit:
                inst.ended, inst.end, inst.returncode = now(), "crashed", code
                s.crash(inst, f"exited with {code} while it ran")
                self.state = "down"
                self.port = None
                self._mark_unhealthy()
                s.timeline.push(now() + 0.5, self.launch, "relaunch", recovery=True, retry=True)

    def kill9(self):
        with self.lock:
            if self.state not in ("up", "frozen", "starting"):
                return False
            inst = self.inst
            inst.expected_exit = True
            inst.proc.kill()
            try:
                inst.proc.wait(10)
            except subprocess.TimeoutExpired:
                pass
            inst.ended, inst.end, inst.returncode = now(), "killed", inst.proc.returncode
            self.state = "down"
            self.port = None
            self._mark_unhealthy()
            return True

    def freeze(self):
        with self.lock:
            if self.state != "up":
                return None
            self.inst.proc.send_signal(signal.SIGSTOP)
            self.state = "frozen"
            self._mark_unhealthy()
            return self.incarnation

    def thaw(self, incarnation):
        with self.lock:
            if self.incarnation != incarnation or self.state != "frozen":
                return
            self.inst.proc.send_signal(signal.SIGCONT)
            self.state = "up"
            self._mark_healthy(now() + 3.0)  # a backlog of a few seconds to work off

    def stop(self):
        """SIGTERM at the end; the exit must be 0 within STOP_TIMEOUT."""
        with self.lock:
            inst = self.inst
            if inst is None or self.state == "down":
                return
            if self.state == "frozen":
                inst.proc.send_signal(signal.SIGCONT)
            inst.expected_exit = True
            inst.proc.send_signal(signal.SIGTERM)
            try:
                inst.proc.wait(STOP_TIMEOUT)
                inst.end = "stopped"
            except subprocess.TimeoutExpired:
                inst.proc.kill()
                inst.proc.wait(10)
                inst.end = "stop-failed"
            inst.ended, inst.returncode = now(), inst.proc.returncode
            self.state = "down"
            self.port = None
            if inst.end != "stopped" or inst.returncode != 0:
                self.soak.crash(inst, f"on the final SIGTERM: {inst.end}, exit {inst.returncode}")

    def kill_quietly(self):
        with self.lock:
            if self.inst is not None and self.inst.proc.poll() is None:
                self.inst.expected_exit = True
                try:
                    self.inst.proc.send_signal(signal.SIGCONT)
                    self.inst.proc.kill()
                    self.inst.proc.wait(10)
                except (OSError, subprocess.TimeoutExpired):
                    pass


# --------------------------------------------------------------------------------------------
# The timeline: fault starts from the seeded schedule, and the recoveries they schedule


class Timeline:
    def __init__(self):
        self.heap = []
        self.cv = threading.Condition()
        self.seq = 0
        self.healing = False
        self.stopped = False
        self.busy = False

    def push(self, t, fn, label, recovery=False, retry=False):
        with self.cv:
            self.seq += 1
            heapq.heappush(self.heap, (t, self.seq, fn, label, recovery, retry))
            self.cv.notify_all()

    def heal(self):
        """From now on no new fault starts; pending recoveries run at once."""
        with self.cv:
            self.healing = True
            self.cv.notify_all()

    def idle(self):
        with self.cv:
            return not self.busy and not any(e[4] and not e[5] for e in self.heap)

    def stop(self):
        with self.cv:
            self.stopped = True
            self.cv.notify_all()

    def run(self, on_error):
        while True:
            with self.cv:
                while True:
                    if self.stopped:
                        return
                    if self.heap:
                        t, _, fn, label, recovery, retry = self.heap[0]
                        due = t <= now() or (self.healing and not retry)
                        if due:
                            heapq.heappop(self.heap)
                            break
                        self.cv.wait(min(0.5, max(0.01, t - now())))
                    else:
                        self.cv.wait(0.5)
                if self.healing and not recovery:
                    continue
                self.busy = True
            try:
                fn()
            except Exception as e:  # noqa: BLE001 - a fault that could not be injected
                on_error(label, e)
            finally:
                with self.cv:
                    self.busy = False


def make_schedule(rng, kinds, seconds, interval, daemons):
    """Fault starts in rounds, each round every kind once in a random order, 0.4-1.6 intervals
    apart; each with its target and durations drawn here, so that the seed fixes them."""
    events = []
    t = rng.uniform(1.5, 3.0)
    while t < seconds:
        order = list(kinds)
        rng.shuffle(order)
        for kind in order:
            if t >= seconds:
                break
            e = {"t": round(t, 2), "kind": kind, "daemon": rng.randrange(daemons)}
            if kind == "kill":
                e["restart_after"] = round(rng.uniform(0.2, 3.0), 2)
            elif kind == "freeze":
                e["past_lease"] = round(rng.uniform(0.5, 2.5), 2)
            elif kind in ("pg-restart", "pg-stop"):
                e["mode"] = rng.choice(["fast", "immediate"])
                e["down"] = round(rng.uniform(2.0, 8.0), 2) if kind == "pg-stop" else 0.0
            elif kind == "disk-full":
                e["fill"] = rng.choice(["enospc", "headroom"])
                e["headroom_kb"] = rng.choice([64, 128, 256, 512])
                e["free"] = rng.choice(["delete", "grow"])
                e["hold"] = round(rng.uniform(2.0, 6.0), 2)
            elif kind == "damage":
                e["variant"] = rng.choice(sorted(DAMAGE))
            elif kind == "disconnect":
                e["variant"] = rng.choice(["half-message", "reset-mid-message",
                                           "unanswered-submit", "abandoned-watch"])
                e["cut"] = round(rng.uniform(0.1, 0.9), 2)
            elif kind == "slowloris":
                e["variant"] = rng.choice(["trickle", "half-then-silence"])
            events.append(e)
            t += rng.uniform(0.4, 1.6) * interval
    return events


# --------------------------------------------------------------------------------------------
# Jobs as the soak knows them


class Job:
    def __init__(self, key, kind, seed, owner):
        self.key = key
        self.kind = kind
        self.seed = seed
        self.owner = owner
        self.job_id = None
        self.acked = None
        self.gave_up = False
        self.cancel_asked = None
        self.damaged = None          # (variant, time)
        self.seen_final = None       # (state, time of the answer)
        self.result_digest = None

    def done(self):
        return self.seen_final is not None or self.damaged is not None


class Soak:
    def __init__(self, args):
        self.args = args
        self.rng = random.Random(f"soak-{args.seed}")
        self.lock = threading.Lock()
        self.failures = collections.defaultdict(list)   # invariant -> evidence lines
        self.counters = collections.Counter()
        self.faults = collections.Counter()
        self.skipped = collections.Counter()
        self.fault_log = []
        self.crashes = []
        self.jobs_by_key = {}
        self.jobs_by_id = {}
        self.known_ids = []
        self.rpc_errors = collections.Counter()
        self.info_latency = []
        self.info_met_fault = 0  # probes whose daemon the schedule froze or killed meanwhile
        self.slow_probes = []
        self.wedged = []
        self.lease_owner = {}          # (job, epoch) -> owner
        self.lease_epoch = {}          # job -> last epoch seen
        self.lease_samples = 0
        self.loris_judged = 0
        self.pg_state = "up"
        self.disk_state = "ok"
        self.store_fault_ended = -math.inf
        self.victims = 0
        self.disconnects = 0
        self.t0 = now()
        self.fillers = []
        self.disk_grown = 0
        self.slots = []
        self.stopping = False
        self.chaos_end = math.inf
        self.drain_deadline = math.inf
        self.timeline = Timeline()
        self.spawner = Spawner()
        self.tag = f"soak{args.seed}"
        self.workdir = args.workdir
        self.logdir = os.path.join(self.workdir, "logs")
        os.makedirs(self.logdir, exist_ok=True)

    # ---- bookkeeping

    def fail(self, invariant, evidence):
        with self.lock:
            self.failures[invariant].append(evidence)
        print(f"FAIL [{invariant}] {evidence}", flush=True)

    def count(self, what, n=1):
        with self.lock:
            self.counters[what] += n

    def crash(self, inst, what):
        evidence = f"{inst.name}: {what}; log tail: {short(inst.log()[-1500:], 1500)}"
        with self.lock:
            self.crashes.append({"daemon": inst.name, "what": what, "time": now()})
        self.fail("crashed", evidence)

    def injected(self, kind, detail):
        with self.lock:
            self.faults[kind] += 1
            self.fault_log.append({"t": round(now() - self.t0, 2), "kind": kind, **detail})
        if self.args.verbose:
            print(f"{now() - self.t0:7.2f} s  {kind} {detail}", flush=True)

    def skip(self, kind, why):
        with self.lock:
            self.skipped[kind] += 1
            self.fault_log.append({"t": round(now() - self.t0, 2), "kind": kind, "skipped": why})

    def store_fault_active(self):
        return self.pg_state != "up" or self.disk_state != "ok"

    def up_slots(self):
        return [s for s in self.slots if s.state == "up"]

    def port_of(self, rng=None):
        """A daemon to talk to: any slot, as a naive client picks (down ones included)."""
        slot = (rng or random).choice(self.slots)
        return slot.port

    # ---- the store, read and written behind the daemons' back

    def sql(self, statement, timeout=10):
        """Rows of a statement on the store (lists of strings), or None when it is unavailable."""
        if self.args.store == "sqlite":
            try:
                db = sqlite3.connect(self.db_path, timeout=5, isolation_level=None)
                try:
                    rows = db.execute(statement).fetchall()
                    return [["" if v is None else str(v) for v in r] for r in rows]
                finally:
                    db.close()
            except sqlite3.Error:
                return None
        try:
            out = subprocess.run([self.psql, "-X", "-q", "-At", "-F", "\x1f", "-h", self.pg_dir,
                                  "-U", "springfit", "-d", "soak", "-c", statement],
                                 capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            return None
        if out.returncode != 0:
            return None
        return [line.split("\x1f") for line in out.stdout.splitlines() if line]

    def pg_ctl(self, *args):
        cmd = [os.path.join(self.pg_bin, "pg_ctl"), "-D", os.path.join(self.pg_dir, "data"),
               "-w", "-t", "60"] + list(args)
        if os.getuid() == 0:
            cmd = ["runuser", "-u", "postgres", "--"] + cmd
        # (pg_ctl's output to a file, never a pipe: a postmaster it starts would hold the pipe)
        with open(os.path.join(self.logdir, "pg_ctl.log"), "ab") as out:
            return subprocess.run(cmd, stdin=subprocess.DEVNULL, stdout=out,
                                  stderr=subprocess.STDOUT, timeout=90).returncode == 0

    # ---- setup

    def setup(self):
        a = self.args
        self.t0 = now()
        self.spawner.start()
        self.scenes = {}
        scene_dir = os.path.join(self.workdir, "scenes")
        os.makedirs(scene_dir, exist_ok=True)
        for kind in a.kinds:
            example, search, _ = JOB_KINDS[kind]
            path = os.path.join(scene_dir, example + ".json")
            if not os.path.exists(path):
                subprocess.run([a.springfit, "example", example, "-o", path], check=True,
                               capture_output=True, timeout=60)
            with open(path) as f:
                scene = json.load(f)
            scene.setdefault("search", {}).update(search)
            self.scenes[kind] = scene
            with open(os.path.join(scene_dir, kind + ".json"), "w") as f:
                json.dump(scene, f)
        self.references()
        if a.store == "sqlite":
            mount = os.path.join(self.workdir, "tmpfs")
            self.tmpfs = mount if "disk-full" in a.faults else None
            if self.tmpfs:
                os.makedirs(mount, exist_ok=True)
                subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={a.tmpfs_mb}m",
                                "springfit-soak", mount], check=True, timeout=30)
                self.db_path = os.path.join(mount, "soak.db")
            else:
                self.db_path = os.path.join(self.workdir, "soak.db")
            self.store_args = ["--db", self.db_path]
        else:
            self.pg_dir = os.environ["SPRINGFIT_TEST_PG_DIR"]
            self.pg_bin = os.environ["SPRINGFIT_TEST_PG_BIN"]
            self.psql = os.path.join(self.pg_bin, "psql")
            for statement in ("DROP DATABASE IF EXISTS soak", "CREATE DATABASE soak"):
                subprocess.run([self.psql, "-X", "-q", "-h", self.pg_dir, "-U", "springfit", "-d",
                                "postgres", "-c", statement], check=True, capture_output=True,
                               timeout=60)
            url = f"postgresql:///soak?host={self.pg_dir}&port=5432&user=springfit"
            self.store_args = ["--store", url, "--store-timeout", "5"]
        self.slots = [Slot(self, i) for i in range(a.daemons)]
        for slot in self.slots:
            slot.launch()
        deadline = now() + START_TIMEOUT
        while now() < deadline and any(s.state != "up" for s in self.slots):
            for s in self.slots:
                s.poll()
            time.sleep(0.05)
        if any(s.state != "up" for s in self.slots):
            raise RuntimeError("the daemons did not start: " + "; ".join(
                f"{s.inst.name}: {short(s.inst.log()[-500:], 500)}" for s in self.slots))

    def references(self):
        """A local `springfit run` of every (kind, seed) the clients draw from, cached by the
        springfit binary's hash: what every succeeded job is compared with."""
        a = self.args
        with open(a.springfit, "rb") as f:
            binary = hashlib.sha256(f.read()).hexdigest()[:12]
        cache = a.reference_cache or os.path.join(self.workdir, "references")
        os.makedirs(cache, exist_ok=True)
        todo = []
        self.ref_paths = {}
        for kind in a.kinds:
            for seed in range(1, a.seeds + 1):
                path = os.path.join(cache, f"{kind}-{seed}-{binary}.json")
                self.ref_paths[(kind, seed)] = path
                if not os.path.exists(path):
                    todo.append((kind, seed, path))
        t0 = now()
        errors = []

        def run(item):
            kind, seed, path = item
            scene = os.path.join(self.workdir, "scenes", kind + ".json")
            tmp = path + f".tmp{os.getpid()}"
            out = subprocess.run([a.springfit, "run", scene, "--seed", str(seed), "--json", "-q",
                                  "--threads", "1", "-o", tmp], capture_output=True, text=True,
                                 timeout=600)
            if out.returncode not in (0, 10, 11):
                errors.append(f"{kind} seed {seed}: exit {out.returncode}: {short(out.stderr)}")
                return
            os.replace(tmp, path)

        pending = list(todo)
        workers = []
        for _ in range(2):
            def work():
                while True:
                    with self.lock:
                        if not pending:
                            return
                        item = pending.pop()
                    run(item)
            th = threading.Thread(target=work)
            th.start()
            workers.append(th)
        for th in workers:
            th.join()
        if errors:
            raise RuntimeError("local reference runs failed: " + "; ".join(errors))
        self.reference_seconds = now() - t0
        self.reference_runs = len(todo)
        self.refs = {}

    def reference(self, kind, seed):
        if (kind, seed) not in self.refs:
            with open(self.ref_paths[(kind, seed)]) as f:
                local = json.load(f)
            trace = strip(local.pop("trace"))
            local.pop("scene_definition", None)
            self.refs[(kind, seed)] = (strip(local), trace)
        return self.refs[(kind, seed)]

    # ---- observations

    def observe(self, job_id, state, t_sent, t_answered, source):
        """A state seen for a job; terminal states must be final and agree with each other."""
        with self.lock:
            job = self.jobs_by_id.get(job_id)
        if job is None:
            return
        if state in TERMINAL:
            if job.seen_final is None:
                job.seen_final = (state, t_answered)
            elif job.seen_final[0] != state:
                self.fail("once", f"job {job_id}: seen {job.seen_final[0]}, later {state} ({source})")
        elif job.seen_final is not None and t_sent > job.seen_final[1] + 0.001:
            self.fail("once", f"job {job_id}: seen {state} ({source}) after it was seen "
                              f"{job.seen_final[0]}")

    def rpc_error(self, method, err, job=None):
        code = err.get("code")
        with self.lock:
            self.rpc_errors[f"{method} {code}"] += 1
        if code == -32603:
            self.fail("crashed", f"{method}: internal error {short(err)}")
        elif code == -32008 and job is not None and job.damaged is None:
            data = err.get("data") or {}
            self.fail("damage", f"{method} of job {job.job_id} (not damaged): {short(err)}"
                      + (" (quarantined)" if data.get("quarantined") else ""))
        elif code == -32002 and job is not None and job.acked is not None:
            self.fail("lost", f"{method}: acknowledged job {job.job_id} is no such job")
        elif code in (-32600, -32601, -32602, -32003, -32004):
            self.fail("soak", f"{method}: {short(err)}")

    # ---- clients

    def submit(self, owner, n, rng, priority=0, patience=60.0):
        kind = rng.choices(self.args.kinds, [JOB_KINDS[k][2] for k in self.args.kinds])[0]
        seed = rng.randint(1, self.args.seeds)
        key = f"{self.tag}-{owner}-{n}"
        job = Job(key, kind, seed, owner)
        with self.lock:
            self.jobs_by_key[key] = job
        params = {"scene": self.scenes[kind], "seed": seed, "label": key,
                  "idempotency_key": key, "priority": priority}
        deadline = min(now() + patience, self.drain_deadline)
        attempts = 0
        while now() < deadline and not self.stopping:
            attempts += 1
            try:
                result, err = rpc(self.port_of(rng), "job.submit", params)
            except Down:
                time.sleep(rng.uniform(0.2, 0.5))
                continue
            if err is not None:
                self.rpc_error("job.submit", err)
                if err.get("code") in (-32007, -32005):
                    time.sleep(rng.uniform(0.3, 0.8))
                    continue
                break
            got = result["job"]
            if got.get("seed") != seed or got.get("label") != key:
                self.fail("once", f"key {key}: answered with job {got.get('job_id')} of seed "
                                  f"{got.get('seed')} label {got.get('label')}")
            with self.lock:
                if job.job_id is not None and job.job_id != got["job_id"]:
                    self.fail("duplicated", f"key {key}: jobs {job.job_id} and {got['job_id']}")
                job.job_id = got["job_id"]
                job.acked = now()
                self.jobs_by_id[job.job_id] = job
                self.known_ids.append(job.job_id)
                if attempts > 1:
                    self.counters["submits retried until acknowledged"] += 1
                if result.get("created") is False:
                    self.counters["submits answered by their key (an earlier try stored it)"] += 1
            self.observe(job.job_id, got.get("state"), 0, now(), "job.submit")
            return job
        job.gave_up = True
        self.count("damage victims never acknowledged" if owner == "victim"
                   else "submits never acknowledged (gave up)")
        return None

    def client(self, c):
        rng = random.Random(f"{self.args.seed}-client-{c}")
        mine = []
        n = 0
        ops = ["poll", "watch", "cancel", "get", "list", "result", "trace", "scene", "info"]
        weights = [5, 3, 1, 2, 1, 2, 1, 1, 1]
        while now() < self.chaos_end and not self.stopping:
            open_jobs = [j for j in mine if not j.done()]
            try:
                if len(open_jobs) < self.args.outstanding:
                    job = self.submit(f"c{c}", n, rng)
                    n += 1
                    if job is not None:
                        mine.append(job)
                    continue
                op = rng.choices(ops, weights)[0]
                self.client_op(op, rng, open_jobs)
            except Exception as e:  # noqa: BLE001 - a soak bug, reported
                self.fail("soak", f"client {c}: {type(e).__name__}: {e}\n{traceback.format_exc()}")
                time.sleep(0.5)
            time.sleep(rng.uniform(0.02, 0.15))
        # The drain: no more submits or cancels; poll until every job of this client ended.
        while now() < self.drain_deadline and not self.stopping:
            open_jobs = [j for j in mine if not j.done()]
            if not open_jobs:
                return
            for job in open_jobs:
                self.poll(job, rng)
            time.sleep(0.3)

    def poll(self, job, rng):
        t = now()
        try:
            result, err = rpc(self.port_of(rng), "job.get", {"job_id": job.job_id})
        except Down:
            return
        if err is not None:
            self.rpc_error("job.get", err, job)
            return
        self.observe(job.job_id, result.get("state"), t, now(), "job.get")

    def client_op(self, op, rng, open_jobs):
        port = self.port_of(rng)
        t = now()
        try:
            if op == "poll":
                for job in open_jobs:
                    self.poll(job, rng)
            elif op == "watch":
                self.watch(rng.choice(open_jobs), port, rng)
            elif op == "cancel":
                job = rng.choice(open_jobs)
                if job.cancel_asked is None:
                    job.cancel_asked = now()
                    self.count("cancels asked")
                result, err = rpc(port, "job.cancel", {"job_id": job.job_id})
                if err is not None and err.get("code") != -32006:
                    self.rpc_error("job.cancel", err, job)
            elif op in ("get", "result", "trace", "scene"):
                with self.lock:
                    if not self.known_ids:
                        return
                    job = self.jobs_by_id[rng.choice(self.known_ids)]
                method = "job." + op
                result, err = rpc(port, method, {"job_id": job.job_id})
                if err is not None:
                    if not (op == "result" and err.get("code") == -32006):
                        self.rpc_error(method, err, job)
                elif op == "get":
                    self.observe(job.job_id, result.get("state"), t, now(), "job.get")
                elif op == "result":
                    self.check_result_digest(job, result)
                elif op == "scene":
                    if result["scene"].get("search", {}).get("seed", 1) != job.seed:
                        self.fail("once", f"job {job.job_id}: stored scene's seed is not {job.seed}")
            elif op == "list":
                params = {"limit": rng.choice([20, 100, 500]),
                          "order": rng.choice(["oldest", "newest"])}
                if rng.random() < 0.5:
                    params["state"] = rng.choice(["queued", "running", "succeeded", "cancelled"])
                result, err = rpc(port, "job.list", params)
                if err is not None:
                    self.rpc_error("job.list", err)
                    return
                for j in result["jobs"]:
                    self.observe(j["job_id"], j["state"], t, now(), "job.list")
                for q in result.get("quarantined") or []:
                    with self.lock:
                        job = self.jobs_by_id.get(q["job_id"])
                    if job is not None and job.damaged is None:
                        self.fail("damage", f"job.list: job {q['job_id']} quarantined, not "
                                            f"damaged by the schedule: {short(q)}")
            elif op == "info":
                result, err = rpc(port, "server.info")
        except (Down, OSError):
            # The daemon went down (killed, its disk full) under the call; a watch's own
            # connection meets it as a refused or reset socket.
            pass

    def check_result_digest(self, job, result):
        if result.get("state") == "succeeded":
            digest = hashlib.sha256(json.dumps(result, sort_keys=True).encode()).hexdigest()
            if job.result_digest is None:
                job.result_digest = digest
            elif job.result_digest != digest:
                self.fail("results", f"job {job.job_id}: its result read twice differs")

    def watch(self, job, port, rng):
        """job.watch until job.finished (at most 8 s); one watch in five abandoned at its first
        progress notification."""
        if port is None:
            return
        abandon = rng.random() < 0.2
        deadline = time.monotonic() + 8.0
        with Conn(port, timeout=CALL_TIMEOUT) as conn:
            t = now()
            conn.send(json.dumps({"jsonrpc": "2.0", "id": 7, "method": "job.watch",
                                  "params": {"job_id": job.job_id}}).encode() + b"\n")
            while True:
                line = conn.read_raw_line(max(deadline - time.monotonic(), 0.0))
                if line is None:
                    return
                msg = json.loads(line)
                if msg.get("id") == 7:
                    if msg.get("error"):
                        self.rpc_error("job.watch", msg["error"], job)
                        return
                    self.observe(job.job_id, msg["result"]["state"], t, now(), "job.watch")
                elif msg.get("method") == "job.finished" and msg["params"].get("job_id") == job.job_id:
                    self.observe(job.job_id, msg["params"]["state"], t, now(), "job.finished")
                    return
                elif msg.get("method") == "job.gone" and msg["params"].get("job_id") == job.job_id:
                    if job.damaged is None:
                        self.fail("damage", f"job.gone for job {job.job_id}: {short(msg)}")
                    return
                elif msg.get("method") == "job.progress" and abandon:
                    self.count("watches abandoned mid-run")
                    return

    # ---- faults

    def fault(self, e):
        kind = e["kind"]
        getattr(self, "fault_" + kind.replace("-", "_"))(e)

    def fault_kill(self, e):
        # (--spare-from-kills K: the last K slots are never killed, so that one process lives
        # through the whole schedule and its memory can be followed.)
        killable = len(self.slots) - self.args.spare_from_kills
        slot = self.slots[e["daemon"] % killable]
        if not slot.kill9():
            return self.skip("kill", "daemon not running")
        if self.args.sabotage != "no-restart":
            self.timeline.push(now() + e["restart_after"], slot.launch, "restart", recovery=True)
        self.injected("kill", {"daemon": slot.inst.name})

    def fault_freeze(self, e):
        slot = self.slots[e["daemon"] % len(self.slots)]
        incarnation = slot.freeze()
        if incarnation is None:
            return self.skip("freeze", "daemon not up")
        hold = self.args.lease_seconds + e["past_lease"]
        self.timeline.push(now() + hold, lambda: slot.thaw(incarnation), "thaw", recovery=True)
        self.injected("freeze", {"daemon": slot.inst.name, "seconds": round(hold, 2)})

    def fault_pg_restart(self, e):
        if self.pg_state != "up":
            return self.skip("pg-restart", "PostgreSQL not up")
        self.pg_state = "restarting"
        self.pg_ctl("stop", "-m", e["mode"])
        self.injected("pg-restart", {"mode": e["mode"]})
        self.pg_start()

    def fault_pg_stop(self, e):
        if self.pg_state != "up":
            return self.skip("pg-stop", "PostgreSQL not up")
        self.pg_state = "down"
        self.pg_ctl("stop", "-m", e["mode"])
        self.injected("pg-stop", {"mode": e["mode"], "seconds": e["down"]})
        self.timeline.push(now() + e["down"], self.pg_start, "pg start", recovery=True)

    def pg_start(self):
        if self.pg_ctl("start", "-l", os.path.join(self.pg_dir, "server.log")):
            self.pg_state = "up"
            self.store_fault_ended = now()
        else:
            self.count("PostgreSQL starts retried")
            self.timeline.push(now() + 1.0, self.pg_start, "pg start", recovery=True, retry=True)

    def tmpfs_size(self):
        st = os.statvfs(self.tmpfs)
        return st.f_blocks * st.f_frsize, st.f_bavail * st.f_frsize

    def fault_disk_full(self, e):
        if self.disk_state != "ok":
            return self.skip("disk-full", "disk already full")
        for path in self.fillers:  # (left by a free that grew the filesystem instead)
            os.remove(path)
        self.fillers = []
        size, free = self.tmpfs_size()
        used = size - free
        base = max(self.args.tmpfs_mb << 20, used + (16 << 20))
        if base != size:
            subprocess.run(["mount", "-o", f"remount,size={base}", self.tmpfs], check=True,
                           timeout=30)
        self.disk_state = "full"
        path = os.path.join(self.tmpfs, f"filler-{len(self.fault_log)}")
        self.fillers.append(path)
        headroom = 0 if e["fill"] == "enospc" else e["headroom_kb"] << 10
        _, free = self.tmpfs_size()
        target = max(0, free - headroom) if headroom else math.inf
        written = 0
        block = b"\0" * (1 << 20)
        with open(path, "wb", buffering=0) as f:
            try:
                while written < target:
                    n = f.write(block if target - written >= len(block) else block[:int(target - written)])
                    written += n
            except OSError as err:
                if err.errno != 28:
                    raise
        self.injected("disk-full", {"fill": e["fill"], "free": e["free"],
                                    "filler_mb": round(written / (1 << 20), 1)})
        self.timeline.push(now() + e["hold"], lambda: self.disk_free(e["free"]), "disk free",
                           recovery=True)

    def disk_free(self, how):
        if how == "delete":
            for path in self.fillers:
                os.remove(path)
            self.fillers = []
        else:
            size, _ = self.tmpfs_size()
            subprocess.run(["mount", "-o", f"remount,size={size + (16 << 20)}", self.tmpfs],
                           check=True, timeout=30)
            self.disk_grown += 1
        self.disk_state = "ok"
        self.store_fault_ended = now()

    def fault_damage(self, e):
        if self.store_fault_active():
            return self.skip("damage", "store unavailable")
        change = DAMAGE[e["variant"]]
        # A queued job of a client if there is one (the newest, which waits longest), else a
        # victim the schedule submits at the lowest priority, damaged at once.
        rows = self.sql("SELECT id FROM jobs WHERE state = 'queued' ORDER BY priority ASC, id DESC LIMIT 3")
        candidates = [int(r[0]) for r in rows or []]
        for attempt in range(3):
            if attempt > 0 or not candidates:
                self.victims += 1
                victim = self.submit("victim", self.victims, self.rng, priority=-1000,
                                     patience=5.0)
                if victim is None:
                    continue
                candidates = [victim.job_id]
            for job_id in candidates:
                with self.lock:
                    job = self.jobs_by_id.get(job_id)
                if job is None or job.done():
                    continue
                # Marked before the write: a client may read the damage the moment it commits.
                job.damaged = (e["variant"], now())
                hit, error = False, None
                if self.args.store == "sqlite":
                    try:
                        db = sqlite3.connect(self.db_path, timeout=5, isolation_level=None)
                        try:
                            hit = db.execute(f"UPDATE jobs SET {change} WHERE id = ? AND state = "
                                             "'queued'", (job_id,)).rowcount == 1
                        finally:
                            db.close()
                    except sqlite3.Error as err:
                        error = f"sqlite: {err}"
                else:
                    rows = self.sql(f"UPDATE jobs SET {change} WHERE id = {job_id} AND state = "
                                    "'queued' RETURNING id")
                    hit = bool(rows)
                if hit:
                    return self.injected("damage", {"job": job_id, "variant": e["variant"]})
                job.damaged = None
                if error:
                    return self.skip("damage", error)
            candidates = []
        self.skip("damage", "no queued job stayed queued")

    def fault_disconnect(self, e):
        threading.Thread(target=self.guard, args=(self.disconnect, e), daemon=True).start()

    def fault_slowloris(self, e):
        threading.Thread(target=self.guard, args=(self.slowloris, e), daemon=True).start()

    def guard(self, fn, e):
        try:
            fn(e)
        except Exception as err:  # noqa: BLE001
            self.skip(e["kind"], f"{type(err).__name__}: {err}")

    def disconnect(self, e):
        slot = self.slots[e["daemon"] % len(self.slots)]
        port = slot.port
        if port is None:
            return self.skip("disconnect", "daemon not running")
        variant = e["variant"]
        kind = self.rng.choice(self.args.kinds)
        with self.lock:
            self.disconnects += 1
            key = f"{self.tag}-dc-{self.disconnects}"
        if variant in ("half-message", "reset-mid-message", "unanswered-submit"):
            seed = random.randint(1, self.args.seeds)
            job = Job(key, kind, seed, "disconnect")
            with self.lock:
                self.jobs_by_key[key] = job
            text = json.dumps({"jsonrpc": "2.0", "id": 1, "method": "job.submit",
                               "params": {"scene": self.scenes[kind], "seed": seed, "label": key,
                                          "idempotency_key": key}}).encode() + b"\n"
            sock = socket.create_connection(("127.0.0.1", port), timeout=CALL_TIMEOUT)
            try:
                if variant == "unanswered-submit":
                    sock.sendall(text)
                else:
                    sock.sendall(text[:max(1, int(len(text) * e["cut"]))])
                    time.sleep(0.05)
                    if variant == "reset-mid-message":
                        sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER,
                                        b"\x01\x00\x00\x00\x00\x00\x00\x00")
            finally:
                sock.close()
        else:  # abandoned-watch: a watch of a running job, closed after its first progress
            with self.lock:
                ids = self.known_ids[-50:]
            if not ids:
                return self.skip("disconnect", "no job to watch")
            with Conn(port, timeout=CALL_TIMEOUT) as conn:
                conn.send(json.dumps({"jsonrpc": "2.0", "id": 1, "method": "job.watch",
                                      "params": {"job_id": random.choice(ids)}}).encode() + b"\n")
                conn.read_raw_line(2.0)
        self.injected("disconnect", {"daemon": slot.inst.name if slot.inst else None,
                                     "variant": variant})

    def slowloris(self, e):
        slot = self.slots[e["daemon"] % len(self.slots)]
        port = slot.port
        if port is None:
            return self.skip("slowloris", "daemon not running")
        text = json.dumps({"jsonrpc": "2.0", "id": 1, "method": "server.info", "params": {}}).encode()
        socks = []
        for _ in range(LORIS_CONNECTIONS):
            try:
                socks.append(socket.create_connection(("127.0.0.1", port), timeout=CALL_TIMEOUT))
            except OSError:
                break
        if not socks:
            return self.skip("slowloris", "no connection")
        t0 = now()
        self.injected("slowloris", {"daemon": slot.inst.name if slot.inst else None,
                                    "variant": e["variant"], "connections": len(socks)})
        closed_at = [None] * len(socks)
        limit = MESSAGE_SECONDS + 4.0
        sent = 0
        for s in socks:
            s.setblocking(False)
            if e["variant"] == "half-then-silence":
                try:
                    s.send(text[:len(text) // 2])
                except OSError:
                    pass
        while now() - t0 < limit and any(c is None for c in closed_at) and not self.stopping:
            for i, s in enumerate(socks):
                if closed_at[i] is not None:
                    continue
                try:
                    if e["variant"] == "trickle" and sent < len(text) - 1:
                        s.send(text[sent:sent + 1])
                    data = s.recv(4096)
                    if data == b"":
                        closed_at[i] = now() - t0
                except (BlockingIOError, InterruptedError):
                    pass
                except OSError:
                    closed_at[i] = now() - t0
            sent += 1
            time.sleep(0.4)
        for s in socks:
            s.close()
        if slot.healthy_during(t0, now()) and not self.stopping:
            self.loris_judged += 1
            late = [round(c, 1) if c is not None else None for c in closed_at
                    if c is None or c > limit]
            if late:
                self.fail("slowloris", f"{slot.inst.name}: {len(late)} of {len(socks)} slow "
                                       f"connections ({e['variant']}) not cut within {limit:.0f} s "
                                       f"(--message-seconds {MESSAGE_SECONDS:.0f}): {late}")

    # ---- monitors

    def monitor(self):
        """Every 0.25 s: starts completed, unplanned exits; every 0.5 s: RSS."""
        tick = 0
        while not self.monitor_stop.is_set():
            for slot in self.slots:
                slot.poll()
                if tick % 2 == 0:
                    with slot.lock:
                        inst = slot.inst
                        if inst is not None and slot.state in ("up", "frozen", "starting"):
                            rss = self.rss(inst.proc.pid)
                            if rss:
                                inst.peak_rss = max(inst.peak_rss, rss)
                                self.rss_series.append((round(now() - self.t0, 1), inst.name, rss))
            tick += 1
            self.monitor_stop.wait(0.25)

    @staticmethod
    def rss(pid):
        try:
            with open(f"/proc/{pid}/status") as f:
                for line in f:
                    if line.startswith("VmRSS:"):
                        return int(line.split()[1]) * 1024
        except OSError:
            pass
        return 0

    def prober(self, slot):
        """server.info once a second while the daemon is up and not frozen: its latency, and
        whether it answers at all (WEDGED_SECONDS)."""
        while not self.monitor_stop.is_set():
            with slot.lock:
                port, healthy_from, inc = slot.port, slot.healthy_from, slot.incarnation
                ready = slot.state == "up" and now() >= healthy_from
            if ready:
                t0 = time.monotonic()
                try:
                    result, err = rpc(port, "server.info", timeout=WEDGED_SECONDS)
                    took = time.monotonic() - t0
                    # A probe in flight when the schedule froze (or killed) its daemon measures
                    # the fault, not the daemon: counted apart. (The hour's soak of round eight
                    # counted them; the trace of the next run showed its one 4 s probe was asked
                    # as its daemon was frozen.)
                    if slot.healthy_during(now() - took, now()):
                        with self.lock:
                            self.info_latency.append(took)
                        if took > SLOW_PROBE_SECONDS:
                            self.slow_probe(slot.inst.name, took)
                    else:
                        with self.lock:
                            self.info_met_fault += 1
                    if err is not None:
                        self.rpc_error("server.info", err)
                except Down as e:
                    took = time.monotonic() - t0
                    # Only if it stayed up and unfrozen the whole time.
                    with slot.lock:
                        still = slot.state == "up" and slot.incarnation == inc
                    if still and slot.healthy_during(now() - took, now()):
                        with self.lock:
                            self.wedged.append({"daemon": slot.inst.name, "t": now() - self.t0,
                                                "error": str(e), "seconds": round(took, 2)})
                        self.fail("wedged", f"{slot.inst.name}: server.info not answered "
                                            f"({e}, {took:.1f} s) while it ran unfrozen")
            self.monitor_stop.wait(1.0)

    def slow_probe(self, daemon, took):
        """A server.info answer over SLOW_PROBE_SECONDS: when, which daemon, and the faults the
        schedule started in the SLOW_PROBE_CONTEXT seconds before it was asked (what it met)."""
        asked = now() - self.t0 - took
        with self.lock:
            near = [f for f in self.fault_log
                    if asked - SLOW_PROBE_CONTEXT <= f["t"] <= asked + took and "skipped" not in f]
            self.slow_probes.append({"t": round(asked, 1), "daemon": daemon,
                                     "seconds": round(took, 2), "faults_before": near})

    def lease_sampler(self):
        """The store's current leases, twice a second: one owner per (job, epoch), epochs of a
        job never going back (beside the store's lease history: check_lease_history)."""
        while not self.monitor_stop.is_set():
            rows = self.sql("SELECT id, lease_owner, lease_epoch FROM jobs WHERE state IN "
                            "('running', 'preparing') AND lease_owner IS NOT NULL", timeout=3)
            if rows is not None:
                self.lease_samples += 1
                for job_id, owner, epoch in rows:
                    job_id, epoch = int(job_id), int(epoch)
                    first = self.lease_owner.setdefault((job_id, epoch), owner)
                    if first != owner:
                        self.fail("two places", f"job {job_id}: lease epoch {epoch} held by "
                                                f"{first} and by {owner}")
                    last = self.lease_epoch.get(job_id, epoch)
                    if epoch < last:
                        self.fail("two places", f"job {job_id}: lease epoch went back from "
                                                f"{last} to {epoch} ({owner})")
                    self.lease_epoch[job_id] = max(last, epoch)
            self.monitor_stop.wait(0.5)

    # ---- the run

    def run(self):
        a = self.args
        self.rss_series = []
        self.monitor_stop = threading.Event()
        self.setup()
        self.schedule = make_schedule(random.Random(f"schedule-{a.seed}"), a.faults, a.seconds,
                                      a.fault_interval, a.daemons)
        threads = [threading.Thread(target=self.monitor, name="monitor", daemon=True),
                   threading.Thread(target=self.lease_sampler, name="leases", daemon=True)]
        threads += [threading.Thread(target=self.prober, args=(s,), daemon=True) for s in self.slots]
        for th in threads:
            th.start()
        self.t_chaos = now()
        print(f"soak: {a.store}, {a.daemons} daemon(s) up, references ready "
              f"({self.reference_runs} run in {self.reference_seconds:.1f} s); {a.seconds:.0f} s "
              f"of chaos ({len(self.schedule)} faults scheduled, seed {a.seed})", flush=True)
        self.chaos_end = self.t_chaos + a.seconds
        self.drain_deadline = self.chaos_end + a.drain_seconds
        for e in self.schedule:
            self.timeline.push(self.t_chaos + e["t"], (lambda e=e: self.fault(e)), e["kind"])
        timeline = threading.Thread(
            target=self.timeline.run,
            args=(lambda label, err: self.skip(label, f"{type(err).__name__}: {err}"),),
            name="timeline", daemon=True)
        timeline.start()
        clients = [threading.Thread(target=self.client, args=(c,), name=f"client{c}", daemon=True)
                   for c in range(a.clients)]
        for th in clients:
            th.start()
        while now() < self.chaos_end:
            time.sleep(0.2)
        self.timeline.heal()
        heal_deadline = now() + 60
        while now() < heal_deadline and not (
                self.timeline.idle() and all(s.state == "up" for s in self.slots)
                and not self.store_fault_active()):
            time.sleep(0.1)
        self.t_healed = now()
        print(f"soak: schedule over, faults healed in {self.t_healed - self.chaos_end:.1f} s; "
              "draining", flush=True)
        if not all(s.state == "up" for s in self.slots):
            self.fail("crashed", "daemons not running 60 s after the schedule ended: " +
                      ", ".join(f"{s.index}: {s.state}" for s in self.slots))
        for th in clients:
            th.join(max(0.1, self.drain_deadline - now() + CALL_TIMEOUT * 3))
        listing = self.drain()
        self.t_drained = now()
        print(f"soak: drained in {self.t_drained - self.t_healed:.1f} s; checking", flush=True)
        self.verify(listing)
        self.timeline.stop()
        self.monitor_stop.set()
        for th in threads:
            th.join(WEDGED_SECONDS + 5)
        for slot in self.slots:
            slot.stop()
        self.after_stop()
        self.stats["seconds"] = {
            "setup": round(self.t_chaos - self.t0, 1), "chaos": a.seconds,
            "heal": round(self.t_healed - self.chaos_end, 1),
            "drain": round(self.t_drained - self.t_healed, 1),
            "check_and_stop": round(now() - self.t_drained, 1), "total": round(now() - self.t0, 1)}

    def list_all(self, patience=30.0):
        """Every job and quarantined job through job.list (which quarantines damaged rows it
        finds), oldest first, page by page; None when no daemon answers within `patience`."""
        deadline = now() + patience
        while now() < deadline:
            jobs, quarantined, cursor = [], [], None
            try:
                port = self.up_slots()[0].port if self.up_slots() else None
                for _page in range(10000):
                    params = {"limit": 1000}
                    if cursor is not None:
                        params["cursor"] = cursor
                    result, err = rpc(port, "job.list", params, timeout=30)
                    if err is not None:
                        raise Down(short(err))
                    jobs += result["jobs"]
                    quarantined += result.get("quarantined") or []
                    cursor = result.get("next_cursor")
                    if cursor is None:
                        return jobs, quarantined
            except Down:
                time.sleep(0.5)
        return None

    def drain(self):
        """Waits until every stored job has ended (or is quarantined), at most --drain-seconds
        after the schedule."""
        listing = None
        while True:
            listing = self.list_all()
            if listing is not None:
                pending = [j for j in listing[0] if j["state"] not in TERMINAL]
                if not pending:
                    return listing
            if now() > self.drain_deadline:
                return listing
            time.sleep(1.0)

    # ---- the checks

    def check_lease_history(self, jobs):
        """two places, from the store's lease history (table leases: every claim of a job, in
        the store's clock, written with the lease): each claim began after the one before had
        ended or expired, epochs rising; every job that ran has its claims there."""
        rows = self.sql("SELECT job_id, epoch, owner, granted_at, expires_at, "
                        "COALESCE(ended_at, -1), COALESCE(ended, '') FROM leases "
                        "ORDER BY job_id, epoch", timeout=60)
        if rows is None:
            self.fail("two places", "the store's lease history could not be read")
            return
        claims = collections.defaultdict(list)
        for r in rows:
            claims[int(r[0])].append((int(r[1]), r[2], float(r[3]), float(r[4]), float(r[5]),
                                      r[6]))
        for job_id, history in claims.items():
            for before, claim in zip(history, history[1:]):
                held_until = before[4] if before[4] >= 0 else before[3]
                if claim[0] <= before[0] or claim[2] < held_until:
                    how = f" ({before[5]})" if before[5] else " (lapsed)"
                    self.fail("two places", f"job {job_id}: claim {claim[0]} by {claim[1]} at "
                                            f"{claim[2]:.3f} while claim {before[0]} by "
                                            f"{before[1]} held it until {held_until:.3f}{how}")
        for j in jobs:
            if j["state"] == "succeeded" and j["job_id"] not in claims:
                self.fail("two places", f"job {j['job_id']} succeeded with no claim in the "
                                        f"store's lease history")
        self.stats["lease_history"] = {
            "claims": sum(len(h) for h in claims.values()), "jobs": len(claims),
            "lapsed": sum(1 for h in claims.values() for c in h[:-1] if c[4] < 0),
            "ended": dict(collections.Counter(c[5] or "lapsed or held"
                                              for h in claims.values() for c in h))}

    def verify(self, listing):
        a = self.args
        self.stats = {}
        if listing is None:
            # What the store holds, read directly: the jobs no daemon could report.
            self.fail("lost", "no daemon answered job.list at the end; the store read directly")
            rows = self.sql("SELECT id, label, state FROM jobs") or []
            listing = ([{"job_id": int(r[0]), "label": r[1], "state": r[2]} for r in rows
                        if r[2] != "quarantined"],
                       [{"job_id": int(r[0]), "state": r[2]} for r in rows if r[2] == "quarantined"])
        jobs, quarantined = listing
        listed = {j["job_id"]: j for j in jobs}
        quarantined_ids = {q["job_id"]: q for q in quarantined}
        with self.lock:
            by_key = dict(self.jobs_by_key)
            by_id = dict(self.jobs_by_id)
        # Jobs stored but never acknowledged (a submit whose answer was lost to a fault, a
        # submit the schedule closed before its answer): known by their labels (= keys).
        labels = collections.Counter(j["label"] for j in jobs)
        for label, n in labels.items():
            if n > 1:
                self.fail("duplicated", f"{n} jobs with the key/label {label}")
        unacked = 0
        for j in jobs:
            job = by_key.get(j["label"])
            if job is None:
                self.fail("lost", f"job {j['job_id']} with an unknown label {j['label']!r}")
                continue
            if job.job_id is None:
                job.job_id = j["job_id"]
                by_id[j["job_id"]] = job
                unacked += 1
            elif job.job_id != j["job_id"]:
                self.fail("duplicated", f"key {job.key}: acknowledged as job {job.job_id}, "
                                        f"stored as job {j['job_id']}")
        store_rows = self.sql("SELECT id, state FROM jobs") or []
        store_state = {int(r[0]): r[1] for r in store_rows}
        q_rows = self.sql("SELECT job_id, previous_state, reason FROM quarantine") or []
        store_quarantine = {int(r[0]): (r[1], r[2]) for r in q_rows}
        # lost: acknowledged, and not stored, or not ended
        acked = [j for j in by_key.values() if j.acked is not None]
        lost, unfinished = [], []
        for job in acked:
            if job.job_id in quarantined_ids:
                continue
            if job.job_id not in listed:
                lost.append(job)
                self.fail("lost", f"job {job.job_id} (key {job.key}) acknowledged, not listed "
                                  f"(store: {store_state.get(job.job_id, 'absent')})")
        for j in jobs:
            if j["state"] not in TERMINAL:
                unfinished.append(j)
                self.fail("lost", f"job {j['job_id']} still {j['state']} "
                                  f"{a.drain_seconds:.0f} s after the schedule")
        # once: the terminal state seen is the final one
        for job in by_id.values():
            j = listed.get(job.job_id)
            if j is not None and job.seen_final is not None and j["state"] != job.seen_final[0]:
                self.fail("once", f"job {job.job_id}: seen {job.seen_final[0]}, ended {j['state']}")
        # damage: exactly the damaged rows quarantined
        damaged = {job.job_id: job for job in by_id.values() if job.damaged is not None}
        for job_id, job in damaged.items():
            if job_id not in quarantined_ids:
                self.fail("damage", f"job {job_id} damaged ({job.damaged[0]}) but not "
                                    f"quarantined: {listed.get(job_id, {}).get('state', 'absent')}")
                continue
            # (The state it had: queued, or the damage itself; cancelled when a client's cancel
            # reached the queued row without reading the damaged column.)
            previous = store_quarantine.get(job_id, (None,))[0]
            if previous not in ("queued", "bogus") and not (
                    previous == "cancelled" and job.cancel_asked is not None):
                self.fail("damage", f"job {job_id}: quarantine row {store_quarantine.get(job_id)}")
        for job_id, q in quarantined_ids.items():
            if job_id not in damaged:
                self.fail("damage", f"job {job_id} quarantined, never damaged: {short(q)}")
        for job_id in store_quarantine:
            if job_id not in damaged:
                self.fail("damage", f"job {job_id} in the store's quarantine, never damaged")
        for job_id in list(damaged)[:20]:
            try:
                result, err = rpc(self.up_slots()[0].port, "job.get", {"job_id": job_id})
                if err is None or err.get("code") != -32008 or \
                        not (err.get("data") or {}).get("quarantined"):
                    self.fail("damage", f"job.get of damaged job {job_id}: "
                                        f"{short(err) if err else result.get('state')}")
            except (Down, IndexError):
                pass
        self.check_lease_history(jobs)
        # cancel, failed
        states = collections.Counter(j["state"] for j in jobs)
        for j in jobs:
            job = by_id.get(j["job_id"])
            if j["state"] == "cancelled" and (job is None or job.cancel_asked is None):
                self.fail("cancel", f"job {j['job_id']} cancelled, never asked to be")
            if j["state"] == "failed":
                self.fail("cancel", f"job {j['job_id']} failed: {short(j.get('error'))}")
        # results: every succeeded job against the local run of its scene and seed
        compared = wrong = 0
        port = self.up_slots()[0].port if self.up_slots() else None
        for j in jobs:
            if j["state"] != "succeeded":
                continue
            job = by_id.get(j["job_id"])
            if job is None:
                continue
            try:
                result, err = rpc(port, "job.result", {"job_id": j["job_id"]}, timeout=30)
                rows, after = [], -1
                while err is None:
                    page, err = rpc(port, "job.trace", {"job_id": j["job_id"], "after": after,
                                                        "limit": 10000}, timeout=30)
                    if err is not None:
                        break
                    rows += page["rows"]
                    if page.get("next_after") is None:
                        break
                    after = page["next_after"]
            except Down as e:
                self.fail("results", f"job {j['job_id']}: result not read: {e}")
                continue
            if err is not None:
                self.fail("results", f"job {j['job_id']}: {short(err)}")
                continue
            self.check_result_digest(job, result)
            local, local_trace = self.reference(job.kind, job.seed)
            if a.sabotage == "wrong-reference" and compared == 0:
                local = dict(local, cost=-1.0)
            compared += 1
            got = strip(result)
            got = {k: v for k, v in got.items() if k in local}
            diff = differences(got, local)
            trace_ok = strip(rows) == local_trace
            if diff or not trace_ok:
                wrong += 1
                self.fail("results", f"job {j['job_id']} ({job.kind}, seed {job.seed}): "
                          + (f"result differs from a local run at {diff}" if diff else "")
                          + ("" if trace_ok else f" trace differs ({len(rows)} rows, local "
                                                 f"{len(local_trace)})"))
        self.stats.update({
            "jobs_acknowledged": len(acked),
            "jobs_stored_unacknowledged": unacked,
            "jobs_by_state": dict(states),
            "jobs_quarantined": len(quarantined_ids),
            "jobs_damaged": len(damaged),
            "lost": len(lost) + len(unfinished),
            "results_compared": compared,
            "results_wrong": wrong,
            "submits_given_up": sum(1 for j in by_key.values() if j.gave_up and j.job_id is None),
        })

    def after_stop(self):
        """The daemons' logs: runs of each job (two places at once), completions (twice),
        crash evidence."""
        runs = collections.defaultdict(list)      # job -> [start, end, kind, instance]
        finals = collections.defaultdict(list)    # job -> [(time, instance, line)]
        resumed = lease_lost = claimed_again = quarantine_lines = 0
        quarantine_logged = collections.Counter()
        line_re = re.compile(r"^(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}) (\w+) (.*)$")
        evidence_re = re.compile(r"AddressSanitizer|ThreadSanitizer|runtime error:|terminate called|"
                                 r"Segmentation fault|internal error \(incident|Assertion .* failed")
        instances = [inst for slot in self.slots for inst in slot.instances]
        for inst in instances:
            open_runs = {}
            for raw in inst.log().splitlines():
                if evidence_re.search(raw):
                    self.fail("crashed", f"{inst.name}: {short(raw, 400)}")
                m = line_re.match(raw)
                if not m:
                    continue
                t, msg = log_time(m.group(1)), m.group(3)
                if (r := re.match(r"job (\d+) running[ ,]", msg)):
                    job = int(r.group(1))
                    if job in open_runs:
                        run = open_runs.pop(job)
                        run[1], run[2] = t, "unknown"
                    run = [t, None, None, inst.name]
                    runs[job].append(run)
                    open_runs[job] = run
                    if "resumed from its checkpoint" in msg:
                        resumed += 1
                    continue
                wrote = re.match(r"job (\d+) (succeeded \(|cancelled \(|failed: |cancelled while "
                                 r"being prepared|cancelled while queued)", msg)
                nowrite = re.match(r"job (\d+)(: lease lost \(| interrupted|: cannot record the "
                                   r"failure)", msg)
                if wrote:
                    job = int(wrote.group(1))
                    finals[job].append((t, inst.name, msg))
                    if job in open_runs:
                        run = open_runs.pop(job)
                        run[1], run[2] = t, "wrote"
                        run.append(msg)
                elif nowrite:
                    job = int(nowrite.group(1))
                    if "cannot record the failure" in msg and finals[job] and \
                            finals[job][-1][1] == inst.name and "failed: " in finals[job][-1][2]:
                        finals[job].pop()      # the failure was not written after all
                        for run in runs[job]:
                            if run[3] == inst.name and run[2] == "wrote":
                                run[2] = "nowrite"
                    if "lease lost (" in msg:
                        lease_lost += 1
                    if job in open_runs:
                        run = open_runs.pop(job)
                        run[1], run[2] = t, "nowrite"
                        run.append(msg)
                elif (r := re.match(r"job (\d+): claimed again", msg)):
                    claimed_again += 1
                elif (r := re.match(r"job (\d+) quarantined \(quarantine incident", msg)):
                    quarantine_logged[int(r.group(1))] += 1
                    quarantine_lines += 1
            for job, run in open_runs.items():
                run[1] = inst.ended or now()
                run[2] = "death" if inst.end in ("killed", "crashed") else "open"
        for job, lines in finals.items():
            if len(lines) > 1:
                self.fail("duplicated", f"job {job} ended more than once: " +
                          "; ".join(f"{name}: {short(msg, 120)}" for _, name, msg in lines))
        overlaps = 0
        for job, rs in runs.items():
            rs.sort(key=lambda r: r[0])
            for i, x in enumerate(rs):
                for y in rs[i + 1:]:
                    if y[0] >= x[1]:
                        continue
                    overlaps += 1
                    if x[2] == "wrote" or x[3] == y[3]:
                        self.fail("two places", f"job {job}: run on {x[3]} ({x[2]}) went on after "
                                                f"{y[3]} started it at {y[0]:.3f} "
                                                f"(ended {x[1]:.3f}: {short(x[4] if len(x) > 4 else '', 100)})")
            ended = [t for t, _, msg in finals.get(job, [])]
            if ended:
                later = [r for r in rs if r[0] > min(ended) + 0.0005]
                if later:
                    self.fail("two places", f"job {job}: run again on {later[0][3]} after it "
                                            f"ended ({short(finals[job][0][2], 100)})")
        for job, n in quarantine_logged.items():
            if n > 1:
                self.fail("damage", f"job {job}: its quarantine logged {n} times")
        # Growth: the longest-lived process, the median of its first and of its last 10 samples.
        samples = collections.defaultdict(list)
        for t, name, rss in self.rss_series:
            samples[name].append(rss)
        longest = max(instances, key=lambda i: (i.ended or now()) - (i.up_at or i.launched))
        series = samples.get(longest.name, [])
        growth = None
        if len(series) >= 20:
            # The median of 10 samples at its start, at each quarter of its life, and at its
            # end: growth that levels off from a leak, which keeps the slope.
            def at(i):
                window = series[max(0, min(i, len(series) - 10)):][:10]
                return round(sorted(window)[len(window) // 2] / (1 << 20), 1)
            growth = {"daemon": longest.name,
                      "seconds": round((longest.ended or now()) - (longest.up_at or longest.launched)),
                      "first_mb": at(0),
                      "quarters_mb": [at(len(series) * q // 4) for q in (1, 2, 3)],
                      "last_mb": at(len(series) - 10)}
        peak = max((inst.peak_rss for inst in instances), default=0)
        if peak > self.args.max_rss_mb << 20:
            worst = max(instances, key=lambda i: i.peak_rss)
            self.fail("memory", f"{worst.name}: peak RSS {worst.peak_rss >> 20} MB over "
                                f"--max-rss-mb {self.args.max_rss_mb}")
        self.stats.update({
            "runs_logged": sum(len(r) for r in runs.values()),
            "resumed_from_checkpoint": resumed,
            "lease_lost_runs": lease_lost,
            "claimed_again_in_one_daemon": claimed_again,
            "overlapping_runs_fenced": overlaps,
            "quarantines_logged": quarantine_lines,
            "instances": len(instances),
            "peak_rss_mb": round(peak / (1 << 20), 1),
            "rss_growth": growth,
            "peak_rss_by_instance": {i.name: round(i.peak_rss / (1 << 20), 1) for i in instances},
            "start_refused": self.counters.get("start refused (store unavailable)", 0),
            "unplanned_exits": len(self.crashes),
            "kills": self.faults.get("kill", 0),
        })

    # ---- the report

    def report(self):
        a = self.args
        s = getattr(self, "stats", {})
        invariants = ["lost", "once", "duplicated", "results", "two places", "crashed", "wedged",
                      "memory", "damage", "cancel", "slowloris", "soak"]
        lat = self.info_latency
        by_state = s.get("jobs_by_state", {})
        duplicated = len(self.failures.get("duplicated", [])) + len(self.failures.get("two places", []))
        lines = []
        lines.append(f"Daemon soak: {a.store}, {a.daemons} daemon{'s' if a.daemons > 1 else ''}, "
                     f"{a.clients} clients, {a.seconds:.0f} s of chaos, seed {a.seed}; "
                     f"{now() - self.t0:.0f} s in all")
        lines.append("")
        lines.append("| fault | injected | skipped |")
        lines.append("|---|---|---|")
        for kind in a.faults:
            lines.append(f"| {kind} | {self.faults.get(kind, 0)} | {self.skipped.get(kind, 0)} |")
        lines.append(f"| all | {sum(self.faults.values())} | {sum(self.skipped.values())} |")
        lines.append("")
        lines.append("| measure | value |")
        lines.append("|---|---|")
        lines.append(f"| jobs | {s.get('jobs_acknowledged', 0)} acknowledged, "
                     f"{s.get('jobs_stored_unacknowledged', 0)} more stored unacknowledged; "
                     + "".join(f"{n} {st}, " for st, n in sorted(by_state.items()))
                     + f"{s.get('jobs_quarantined', 0)} quarantined "
                       f"({s.get('jobs_damaged', 0)} damaged) |")
        lines.append(f"| lost | {s.get('lost', 0)} |")
        lines.append(f"| duplicated (twice stored, ended or run at once) | {duplicated} |")
        lines.append(f"| crashed (unplanned exits and crash evidence) | "
                     f"{len(self.failures.get('crashed', []))} |")
        lines.append(f"| results different from a local run | {s.get('results_wrong', 0)} of "
                     f"{s.get('results_compared', 0)} |")
        lines.append(f"| peak memory (RSS) | {s.get('peak_rss_mb', 0)} MB, the largest of "
                     f"{s.get('instances', 0)} daemon processes (bound {a.max_rss_mb} MB) |")
        g = s.get("rss_growth")
        if g:
            quarters = " / ".join(f"{mb}" for mb in g.get("quarters_mb", []))
            lines.append(f"| memory of the longest-lived daemon process | {g['daemon']}, "
                         f"{g['seconds']} s: {g['first_mb']} MB at its start, {quarters} MB at "
                         f"a quarter, half and three quarters of its life, {g['last_mb']} MB at "
                         f"its end |")
        if lat:
            lines.append(f"| server.info latency | median {percentile(lat, 50) * 1000:.1f} ms, p99 "
                         f"{percentile(lat, 99) * 1000:.0f} ms, max {max(lat) * 1000:.0f} ms "
                         f"({len(lat)} probes of running daemons; {sum(1 for x in lat if x > 1)} "
                         f"over 1 s; {getattr(self, 'info_met_fault', 0)} more met a freeze or "
                         f"kill of their daemon, left out) |")
        for slow in getattr(self, "slow_probes", []):
            before = ", ".join(f"{f['kind']} at {f['t']:.0f} s"
                               + (f" ({f['daemon']})" if f.get("daemon") else "")
                               for f in slow["faults_before"]) or "no fault"
            lines.append(f"| slow server.info | {slow['daemon']} at {slow['t']:.0f} s: "
                         f"{slow['seconds']} s; the {SLOW_PROBE_CONTEXT:.0f} s before: {before} |")
        lines.append(f"| resumed from a checkpoint / lease lost (fenced) / runs overlapping a "
                     f"frozen one | {s.get('resumed_from_checkpoint', 0)} / "
                     f"{s.get('lease_lost_runs', 0)} / {s.get('overlapping_runs_fenced', 0)} |")
        lines.append(f"| lease samples | {self.lease_samples} ({len(self.lease_owner)} job epochs) |")
        history = s.get("lease_history", {})
        lines.append(f"| store's lease history: claims / jobs / lapsed and claimed again | "
                     f"{history.get('claims', 0)} / {history.get('jobs', 0)} / "
                     f"{history.get('lapsed', 0)} |")
        lines.append(f"| starts refused while the store was unavailable | "
                     f"{s.get('start_refused', 0)} |")
        lines.append(f"| submits retried until acknowledged / never acknowledged (clients; "
                     f"damage victims, 5 s each) | "
                     f"{self.counters.get('submits retried until acknowledged', 0)} / "
                     f"{self.counters.get('submits never acknowledged (gave up)', 0)}; "
                     f"{self.counters.get('damage victims never acknowledged', 0)} |")
        lines.append(f"| slow-loris attacks judged (target healthy throughout) | {self.loris_judged} |")
        if "seconds" in s:
            t = s["seconds"]
            lines.append(f"| time (s) | setup {t['setup']}, chaos {t['chaos']:.0f}, heal {t['heal']}, "
                         f"drain {t['drain']}, checks and stop {t['check_and_stop']}; total "
                         f"{t['total']} |")
        if self.counters.get("cancels asked"):
            lines.append(f"| cancels asked | {self.counters['cancels asked']} |")
        if self.rpc_errors:
            top = ", ".join(f"{k}: {n}" for k, n in self.rpc_errors.most_common(6))
            lines.append(f"| error answers (method code: count) | {top} |")
        lines.append("")
        for inv in invariants:
            ev = self.failures.get(inv, [])
            lines.append(f"{'FAIL' if ev else 'PASS'}: {inv}" + (f" ({len(ev)})" if ev else ""))
            for line in ev[:5]:
                lines.append(f"    {short(line, 600)}")
            if len(ev) > 5:
                lines.append(f"    ... and {len(ev) - 5} more")
        ok = not any(self.failures.values())
        lines.append("SOAK PASSED" if ok else "SOAK FAILED")
        print("\n".join(lines), flush=True)
        if a.json:
            out = {"args": {k: v for k, v in vars(a).items() if k not in ("inner",)},
                   "passed": ok, "stats": s, "faults": dict(self.faults),
                   "skipped": dict(self.skipped), "failures": dict(self.failures),
                   "counters": dict(self.counters), "rpc_errors": dict(self.rpc_errors),
                   "server_info_latency": {"count": len(lat), "median": percentile(lat, 50),
                                           "p99": percentile(lat, 99),
                                           "max": max(lat) if lat else None,
                                           "slow": getattr(self, "slow_probes", []),
                                           "met_fault": getattr(self, "info_met_fault", 0)},
                   "schedule": getattr(self, "schedule", []), "fault_log": self.fault_log,
                   "crashes": self.crashes, "wedged": self.wedged,
                   "reference_runs": getattr(self, "reference_runs", 0),
                   "rss_series_tail": self.rss_series[-200:] if hasattr(self, "rss_series") else []}
            with open(a.json, "w") as f:
                json.dump(out, f, indent=1, default=str)
        return ok

    def cleanup(self):
        self.stopping = True
        self.timeline.stop()
        if hasattr(self, "monitor_stop"):
            self.monitor_stop.set()
        for slot in self.slots:
            slot.kill_quietly()
        if self.args.store == "postgres" and getattr(self, "pg_state", "up") != "up":
            self.pg_ctl("start", "-l", os.path.join(self.pg_dir, "server.log"))
        self.spawner.stop()


# --------------------------------------------------------------------------------------------


def parse(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--store", choices=["sqlite", "postgres"], default="sqlite")
    p.add_argument("--daemons", type=int, help="default 1 (sqlite), 3 (postgres)")
    p.add_argument("--clients", type=int, default=4)
    p.add_argument("--seconds", type=float, default=60.0, help="length of the chaos schedule")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--json", help="write the figures, schedule and failures here")
    p.add_argument("--springfitd", default=os.path.join(ROOT, "build", "server", "springfitd"))
    p.add_argument("--springfit", default=os.path.join(ROOT, "build", "client", "springfit"))
    p.add_argument("--faults", help="comma-separated fault kinds (default: all of the store's: "
                                    "sqlite " + ",".join(FAULTS["sqlite"]) + "; postgres "
                                    + ",".join(FAULTS["postgres"]) + ")")
    p.add_argument("--fault-interval", type=float, default=3.0,
                   help="mean seconds between fault starts (default 3)")
    p.add_argument("--kinds", default=",".join(JOB_KINDS),
                   help="job kinds (default all: " + ",".join(JOB_KINDS) + ")")
    p.add_argument("--seeds", type=int, default=3, help="job seeds drawn from 1..K (default 3)")
    p.add_argument("--outstanding", type=int, default=3, help="unfinished jobs per client")
    p.add_argument("--lease-seconds", type=float, default=3.0)
    p.add_argument("--daemon-workers", type=int, help="default 2 (sqlite), 1 (postgres)")
    p.add_argument("--daemon-jobs", type=int, default=2)
    p.add_argument("--drain-seconds", type=float, default=90.0,
                   help="after the schedule, how long every job has to end (default 90)")
    p.add_argument("--max-rss-mb", type=int, default=512)
    p.add_argument("--spare-from-kills", type=int, default=0,
                   help="the last K daemons are never killed (other faults still hit them), so "
                        "that their memory is followed through the whole schedule")
    p.add_argument("--tmpfs-mb", type=int, default=64)
    p.add_argument("--reference-cache", help="directory of local reference runs, kept "
                                             "(default: in the temporary directory)")
    p.add_argument("--keep", action="store_true", help="keep the temporary directory")
    p.add_argument("--verbose", action="store_true", help="print each fault as it is injected")
    p.add_argument("--sabotage", choices=["none", "no-restart", "wrong-reference"], default="none",
                   help="break the soak on purpose, to see an invariant fail: kills without "
                        "restarts, or one local reference changed")
    p.add_argument("--workdir", help=argparse.SUPPRESS)
    p.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    a.daemons = a.daemons or (1 if a.store == "sqlite" else 3)
    a.daemon_workers = a.daemon_workers or (2 if a.store == "sqlite" else 1)
    if a.store == "sqlite" and a.daemons != 1:
        p.error("--store sqlite runs one daemon (one daemon per SQLite database)")
    if not 0 <= a.spare_from_kills < a.daemons:
        p.error("--spare-from-kills must leave at least one daemon to kill")
    a.faults = a.faults.split(",") if a.faults else list(FAULTS[a.store])
    for f in a.faults:
        if f not in FAULTS[a.store]:
            p.error(f"fault {f!r} is not one of {a.store}'s: {', '.join(FAULTS[a.store])}")
    a.kinds = a.kinds.split(",")
    for k in a.kinds:
        if k not in JOB_KINDS:
            p.error(f"job kind {k!r} is not one of {', '.join(JOB_KINDS)}")
    a.springfitd = os.path.abspath(a.springfitd)
    a.springfit = os.path.abspath(a.springfit)
    if a.json:
        a.json = os.path.abspath(a.json)
    if a.reference_cache:
        a.reference_cache = os.path.abspath(a.reference_cache)
    for path in (a.springfitd, a.springfit):
        if not os.access(path, os.X_OK):
            p.error(f"not an executable: {path}")
    return a


def inner(argv):
    args = parse(argv)
    soak = Soak(args)

    def terminate(signum, frame):
        raise KeyboardInterrupt(f"signal {signum}")

    signal.signal(signal.SIGTERM, terminate)
    ok = False
    try:
        soak.run()
        ok = soak.report()
    except KeyboardInterrupt as e:
        print(f"soak interrupted: {e}", flush=True)
    except Exception as e:  # noqa: BLE001 - reported with the evidence so far
        soak.fail("soak", f"{type(e).__name__}: {e}\n{traceback.format_exc()}")
        soak.report()
    finally:
        soak.cleanup()
    return 0 if ok else 1


def outer(argv):
    """Sets the stage and runs the soak inside it: a private PostgreSQL server
    (tests/server/with_postgres.sh) or a private mount namespace for the tmpfs; removes the
    temporary directory afterwards, whatever happened."""
    args = parse(argv)
    workdir = tempfile.mkdtemp(prefix="springfit-soak-")
    cmd = [sys.executable, os.path.abspath(__file__)] + argv + ["--inner", "--workdir", workdir]
    if args.store == "postgres" and not os.environ.get("SPRINGFIT_TEST_PG_DIR"):
        cmd = [WITH_POSTGRES] + cmd
    if args.store == "sqlite" and "disk-full" in args.faults:
        if subprocess.run(["unshare", "--mount", "--propagation", "private", "true"],
                          capture_output=True).returncode == 0:
            cmd = ["unshare", "--mount", "--propagation", "private"] + cmd
        elif subprocess.run(["unshare", "--map-root-user", "--mount", "true"],
                            capture_output=True).returncode == 0:
            cmd = ["unshare", "--map-root-user", "--mount"] + cmd
        else:
            shutil.rmtree(workdir, ignore_errors=True)
            print("soak: the disk-full fault needs a tmpfs in a private mount namespace (unshare "
                  "--mount, as root or with user namespaces); leave it out with --faults",
                  file=sys.stderr)
            return 2
    proc = subprocess.Popen(cmd, start_new_session=True)

    def forward(signum, frame):
        try:
            proc.send_signal(signal.SIGTERM)
        except OSError:
            pass

    signal.signal(signal.SIGTERM, forward)
    signal.signal(signal.SIGINT, forward)
    try:
        while True:
            try:
                code = proc.wait()
                break
            except KeyboardInterrupt:
                forward(signal.SIGINT, None)
    finally:
        # Whatever is left of the soak's process group (nothing, normally).
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except OSError:
            pass
        if args.keep:
            print(f"soak: kept {workdir}")
        else:
            shutil.rmtree(workdir, ignore_errors=True)
    return code


if __name__ == "__main__":
    argv = sys.argv[1:]
    sys.exit(inner(argv) if "--inner" in argv else outer(argv))
