"""Client: one connection to springfitd, speaking JSON-RPC 2.0 over TCP (proto/RPC.md)."""

import copy
import json
import os
import socket
import subprocess
import time

from .errors import (NO_SUCH_JOB, CliError, RpcError, ServerConnectionError, ServerTimeout,
                     WatchTimeout)
from .records import Improvement, Job, Phase, Progress, Result, ServerInfo, Submission, TraceRow

__all__ = ["Client", "DEFAULT_SERVER", "DEFAULT_TIMEOUT", "parse_server_address"]

DEFAULT_SERVER = "127.0.0.1:7117"   # springfit's default (client/rpc_client.cpp)
DEFAULT_TIMEOUT = 60.0              # springfit's --timeout default
_MESH_SUFFIXES = (".msh", ".inp")   # what springfit imports (io/mesh_import.h)
_TRACE_PAGE = 10000                 # job.trace's largest page
_LIST_PAGE = 1000


def parse_server_address(text):
    """"HOST:PORT", "[::1]:PORT" -> (host, port), as springfit reads --server."""
    colon = text.rfind(":")
    if colon <= 0 or colon + 1 == len(text):
        raise ValueError(f"server address: expected HOST:PORT, got {text!r}")
    host, port = text[:colon], text[colon + 1:]
    if len(host) >= 2 and host[0] == "[" and host[-1] == "]":
        host = host[1:-1]
    if not port.isdigit() or int(port) > 65535:
        raise ValueError(f"server address: port {port!r} is not a number in [0, 65535]")
    return host, int(port)


def _read_token_file(path):
    try:
        with open(path, encoding="utf-8") as f:
            token = f.read()
    except OSError as e:
        raise ValueError(f"token file {path}: {e.strerror or e}") from None
    token = token.rstrip()
    if not token:
        raise ValueError(f"token file {path}: the token is empty")
    return token


# Client.submit's search options: keyword -> the scene's `search` member (proto/SCENE.md,
# "Search"), as `springfit submit`'s flags of the same names write them.
_SEARCH_OPTIONS = {
    "strategy": "strategy", "identify": "identify", "generations": "max_generations",
    "time_limit": "max_seconds", "stall": "stall_generations", "response": "response",
    "max_springs": "max_springs", "target_error": "target_error", "max_spread": "max_spread",
    "load_size": "load_size", "regularization": "regularization", "probes": "probes",
}


class Client:
    """A connection to springfitd.

    server: "HOST:PORT"; default $SPRINGFIT_SERVER, else 127.0.0.1:7117 (as springfit).
    token / token_file: the daemon's token (a file's trailing whitespace is dropped); default
    $SPRINGFIT_TOKEN, as springfit. With one, the connection calls session.auth first.
    timeout: seconds to connect, and to wait for each answer (a submission being prepared
    counts from its last job.preparing notice); not for a watched job's next notification.
    springfit: the springfit program that import and export run (default: on PATH).

    Connects on the first call (or on connect()). After a ServerConnectionError the connection
    is dropped and the next call connects anew. One Client is one connection: use one per
    thread. A context manager: `with Client() as c: ...` closes it at the end.
    """

    def __init__(self, server=None, token=None, token_file=None, timeout=DEFAULT_TIMEOUT,
                 springfit="springfit"):
        if token is not None and token_file is not None:
            raise ValueError("pass token or token_file, not both")
        if server is None:
            server = os.environ.get("SPRINGFIT_SERVER") or DEFAULT_SERVER
        self.host, self.port = parse_server_address(server)
        self.server = server
        self.token_file = token_file
        if token_file is not None:
            token = _read_token_file(token_file)
        elif token is None:
            token = os.environ.get("SPRINGFIT_TOKEN") or None
        if token is not None:
            token = token.rstrip()
            if not token:
                raise ValueError("the token is empty")
        self._token = token
        if timeout is None or timeout <= 0:
            raise ValueError("timeout: a number of seconds > 0")
        self.timeout = float(timeout)
        self.springfit = springfit
        self._sock = None
        self._buf = b""
        self._next_id = 1
        self._notifications = []   # job.progress, job.finished, job.gone read during a call

    # ----------------------------------------------------------------------------------------
    # The connection

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self):
        return f"Client({self.server!r}, {'connected' if self._sock else 'not connected'})"

    def connect(self):
        """Connects (and authenticates) now rather than on the first call."""
        if self._sock is not None:
            return
        where = f"{self.host}:{self.port}"
        try:
            sock = socket.create_connection((self.host, self.port), timeout=self.timeout)
        except socket.timeout:
            raise ServerTimeout(f"cannot connect to springfitd at {where}: no answer within "
                                f"{self.timeout:g} s (timeout)") from None
        except OSError as e:
            raise ServerConnectionError(f"cannot connect to springfitd at {where}: "
                                        f"{e.strerror or e}") from None
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._sock, self._buf, self._notifications = sock, b"", []
        if self._token is not None:
            try:
                self.call("session.auth", {"token": self._token})
            except RpcError:
                self.close()
                raise

    def close(self):
        if self._sock is not None:
            try:
                self._sock.close()
            except OSError:
                pass
        self._sock = None
        self._buf = b""
        self._notifications = []

    def _lost(self, what):
        self.close()
        return ServerConnectionError(f"connection to springfitd at {self.host}:{self.port} "
                                     f"{what}")

    def _read_message(self, deadline):
        """The next message (one line of JSON); deadline None waits for ever."""
        while True:
            newline = self._buf.find(b"\n")
            if newline >= 0:
                line, self._buf = self._buf[:newline], self._buf[newline + 1:]
                if not line.strip():
                    continue
                try:
                    message = json.loads(line)
                except ValueError as e:
                    raise self._lost(f"broken: it sent something that is not JSON ({e})") from None
                if not isinstance(message, dict):
                    raise self._lost(f"broken: it sent {type(message).__name__}, not an object")
                return message
            if deadline is None:
                self._sock.settimeout(None)
            else:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise self._timeout()
                self._sock.settimeout(remaining)
            try:
                chunk = self._sock.recv(1 << 20)
            except socket.timeout:
                raise self._timeout() from None
            except OSError as e:
                raise self._lost(f"lost: {e.strerror or e}") from None
            if not chunk:
                raise self._lost("lost: closed by the server")
            self._buf += chunk

    def _timeout(self):
        self.close()
        return ServerTimeout(f"springfitd at {self.host}:{self.port} did not answer within "
                             f"{self.timeout:g} s (timeout)")

    def call(self, method, params=None, on_preparing=None):
        """Sends one request and returns its result (the JSON value). Raises RpcError for an
        error answer, ServerConnectionError (ServerTimeout) when there is none.

        Notifications that arrive meanwhile are kept for watch(); job.preparing notices go to
        on_preparing(params) and restart the answer's timeout.
        """
        self.connect()
        request_id = self._next_id
        self._next_id += 1
        request = {"jsonrpc": "2.0", "id": request_id, "method": method}
        if params is not None:
            request["params"] = params
        data = json.dumps(request, separators=(",", ":"), ensure_ascii=False,
                          allow_nan=False).encode("utf-8") + b"\n"
        try:
            self._sock.settimeout(self.timeout)
            self._sock.sendall(data)
        except socket.timeout:
            raise self._timeout() from None
        except OSError as e:
            raise self._lost(f"lost: {e.strerror or e}") from None
        deadline = time.monotonic() + self.timeout
        while True:
            message = self._read_message(deadline)
            if "id" not in message:   # a notification
                if message.get("method") == "job.preparing":
                    deadline = time.monotonic() + self.timeout
                    if on_preparing is not None:
                        on_preparing(message.get("params") or {})
                else:
                    self._notifications.append(message)
                continue
            if message.get("id") not in (request_id, None):
                continue   # not ours (cannot happen: one request at a time)
            error = message.get("error")
            if isinstance(error, dict):
                raise RpcError(error.get("code"), error.get("message") or "error",
                               error.get("data"), method)
            if message.get("id") is None:
                continue
            return message.get("result")

    # ----------------------------------------------------------------------------------------
    # Methods

    def info(self):
        """server.info: the daemon's version, workers, jobs and limits (no token needed)."""
        return ServerInfo.from_json(self.call("server.info"))

    def submit(self, scene, label=None, priority=None, seed=None, idempotency_key=None,
               search=None, on_preparing=None, **options):
        """Queues a job; returns its id. See submit_job for the arguments."""
        return self.submit_job(scene, label=label, priority=priority, seed=seed,
                               idempotency_key=idempotency_key, search=search,
                               on_preparing=on_preparing, **options).job.job_id

    def submit_job(self, scene, label=None, priority=None, seed=None, idempotency_key=None,
                   search=None, on_preparing=None, **options):
        """job.submit: returns a Submission (`created`, `job`).

        scene: a scene (dict, proto/SCENE.md) or the path of a scene file (JSON; a .msh or
        .inp file is imported by `springfit import`: see submit_mesh, which takes loads too).
        label, priority ([-1000, 1000]), seed, idempotency_key: as proto/RPC.md. The search
        options of `springfit submit`, written into the scene's `search` (a copy; the
        caller's dict is not changed): strategy, identify, generations,
        time_limit, stall, response, max_springs, target_error, max_spread, load_size,
        regularization, probes
        ("auto" drops the scene's); search: further `search` members as proto/SCENE.md names
        them (e.g. {"population": 40}). on_preparing(params): called with each job.preparing
        notice of a scene that takes the daemon more than a second to prepare.
        """
        unknown = sorted(set(options) - set(_SEARCH_OPTIONS))
        if unknown:
            raise TypeError(f"submit: unknown options {', '.join(unknown)} (known: "
                            f"{', '.join(_SEARCH_OPTIONS)}, search=...)")
        if isinstance(scene, (str, os.PathLike)):
            if os.fspath(scene).lower().endswith(_MESH_SUFFIXES):
                scene = self.import_scene(scene)   # as springfit submit MESH does
            else:
                with open(scene, encoding="utf-8") as f:
                    scene = json.load(f)
        if not isinstance(scene, dict):
            raise TypeError("scene: a dict (proto/SCENE.md) or a scene file's path")
        given = {k: v for k, v in options.items() if v is not None}
        if given or search:
            scene = copy.deepcopy(scene)
            settings = scene.get("search")
            settings = dict(settings) if isinstance(settings, dict) else {}
            settings.update(search or {})
            for option, value in given.items():
                if option == "probes" and value == "auto":
                    settings.pop("probes", None)   # the default
                else:
                    settings[_SEARCH_OPTIONS[option]] = value
            scene["search"] = settings
        params = {"scene": scene}
        for name, value in (("label", label), ("priority", priority), ("seed", seed),
                            ("idempotency_key", idempotency_key)):
            if value is not None:
                params[name] = value
        return Submission.from_json(self.call("job.submit", params, on_preparing=on_preparing))

    def import_scene(self, mesh_path, loads_path=None, more=(), results=()):
        """The scene `springfit import` makes of a mesh (.msh) or CalculiX/Abaqus decks (.inp;
        `more`: further decks, `results`: their .frd/.dat answers) and a loads file
        (proto/IMPORT.md), as a dict. Raises CliError when springfit refuses them."""
        args = ["import", os.fspath(mesh_path)] + [os.fspath(p) for p in more]
        if loads_path is not None:
            args += ["--loads", os.fspath(loads_path)]
        if results:
            args += ["--results"] + [os.fspath(p) for p in results]
        out = self._run_springfit(args, server=False)
        try:
            return json.loads(out)
        except ValueError as e:
            raise CliError([self.springfit] + args, 0, f"not a JSON scene: {e}") from None

    def submit_mesh(self, mesh_path, loads_path=None, more=(), results=(), **submit_args):
        """Imports a mesh or decks (import_scene) and submits the scene; returns the job id.
        submit_args: those of submit (label, seed, strategy, ...)."""
        return self.submit(self.import_scene(mesh_path, loads_path, more, results), **submit_args)

    def status(self, job_id):
        """job.get: the Job. RpcError NO_SUCH_JOB for an unknown id."""
        return Job.from_json(self.call("job.get", {"job_id": job_id}))

    def watch(self, job_id, on_progress=None, poll_interval=None, timeout=None, on_phase=None):
        """Follows a job until it finishes; returns the finished Job (its .verdict, .outcome).

        on_progress(Progress): called for each job.progress notification (at most four a
        second; the server always sends generation 0), then once with the finished job's last
        row (Progress.final True) unless that row was reported already: at least once for
        every job that reached its search, even one finished before the watch began.
        on_phase(Phase): called for each job.phase notification of a job that the daemon
        watched runs itself (each phase's first beat, then at most four a second): where a step
        has got between rows, the analysis, a fit's steps, the certificate.
        poll_interval: None follows the job through job.watch's notifications; a number of
        seconds polls job.get at that interval instead (reporting each new generation).
        timeout: None waits as long as the job takes; seconds raise WatchTimeout (the job
        goes on running). A job that disappears (a submission refused while it was being
        prepared) raises RpcError NO_SUCH_JOB.
        """
        deadline = None if timeout is None else time.monotonic() + timeout
        if poll_interval is not None:
            return self._watch_polling(job_id, on_progress, poll_interval, deadline)
        job = Job.from_json(self.call("job.watch", {"job_id": job_id}))
        reported = None   # the generation last reported
        try:
            while True:
                message = self._next_notification(deadline, job)
                params = message.get("params")
                if not isinstance(params, dict) or params.get("job_id") != job_id:
                    continue
                method = message.get("method")
                if method == "job.progress":
                    if on_progress is not None:
                        on_progress(Progress.from_json(params))
                    reported = params.get("generation")
                elif method == "job.phase":
                    if on_phase is not None:
                        on_phase(Phase.from_json(params))
                elif method == "job.finished":
                    job = Job.from_json(params)
                    self._report_final(job, reported, on_progress)
                    return job
                elif method == "job.gone":
                    raise RpcError(NO_SUCH_JOB, params.get("message") or "the job is gone",
                                   {"job_id": job_id}, "job.watch")
        except BaseException:
            # A watch left open would send on: the connection is dropped (the next call
            # connects anew); the job goes on on the server.
            self.close()
            raise

    def _next_notification(self, deadline, job):
        if self._notifications:
            return self._notifications.pop(0)
        try:
            return self._read_message(deadline)
        except ServerTimeout:
            if deadline is not None and time.monotonic() >= deadline:
                raise WatchTimeout(f"job {job.job_id} has not finished within the watch's "
                                   f"timeout (state {job.state})", job) from None
            raise

    def _watch_polling(self, job_id, on_progress, interval, deadline):
        reported = None
        while True:
            job = self.status(job_id)
            if job.finished:
                self._report_final(job, reported, on_progress)
                return job
            if job.progress is not None and job.progress.generation != reported:
                reported = job.progress.generation
                if on_progress is not None:
                    on_progress(self._progress_of(job, final=False))
            if deadline is not None and time.monotonic() + interval > deadline:
                raise WatchTimeout(f"job {job_id} has not finished within the watch's timeout "
                                   f"(state {job.state})", job)
            time.sleep(interval)

    @staticmethod
    def _progress_of(job, final):
        row = dict(job.progress.raw)
        row.setdefault("job_id", job.job_id)
        row.setdefault("max_generations", job.max_generations)
        return Progress.from_json(row, final=final)

    def _report_final(self, job, reported, on_progress):
        if on_progress is not None and job.progress is not None and \
                job.progress.generation != reported:
            on_progress(self._progress_of(job, final=True))

    def wait(self, job_id, timeout=None, on_progress=None):
        """watch(), returning the Result of a job that has one (succeeded, or cancelled while
        running); raises RpcError WRONG_STATE for a failed job (its error in the message) or
        one cancelled before it ran."""
        self.watch(job_id, on_progress=on_progress, timeout=timeout)
        return self.result(job_id)

    def result(self, job_id):
        """job.result: the Result of a succeeded job (or the best so far of one cancelled while
        running). RpcError WRONG_STATE for a job without one (data["state"])."""
        return Result.from_json(self.call("job.result", {"job_id": job_id}))

    def trace(self, job_id, after=-1):
        """Every stored trace row (generation > after) as TraceRows, all pages followed."""
        rows = []
        while True:
            page = self.call("job.trace", {"job_id": job_id, "after": after, "limit": _TRACE_PAGE})
            rows += [TraceRow.from_json(r) for r in page.get("rows") or []]
            after = page.get("next_after")
            if after is None:
                return rows

    def improvements(self, job_id, last=False):
        """Every improvement of the job's best topology, oldest first (Improvement); last=True:
        the newest alone (a list of at most one)."""
        params = {"job_id": job_id}
        if last:
            page = self.call("job.improvements", dict(params, last=True))
            return [Improvement.from_json(r) for r in page.get("improvements") or []]
        rows, after = [], -1
        while True:
            page = self.call("job.improvements", dict(params, after=after))
            rows += [Improvement.from_json(r) for r in page.get("improvements") or []]
            after = page.get("next_after")
            if after is None:
                return rows

    def scene(self, job_id):
        """job.scene: the stored scene (a dict), with the job's seed written in."""
        return self.call("job.scene", {"job_id": job_id}).get("scene")

    def cancel(self, job_id):
        """job.cancel: returns the job's new state, "cancelled" (it was queued) or "cancelling"
        (it was running or being prepared; it stops within a second, watch() sees it end).
        RpcError WRONG_STATE for a finished job."""
        return self.call("job.cancel", {"job_id": job_id}).get("state")

    def delete(self, job_id):
        """job.delete: deletes a finished job and all that is stored with it. RpcError
        WRONG_STATE for one not finished (cancel it first)."""
        self.call("job.delete", {"job_id": job_id})

    def iter_jobs(self, state=None, label=None, limit=None, order="oldest", cursor=None):
        """Jobs (Job), page after page, in submission order (order "newest": newest first),
        filtered by state and label, at most `limit` of them (None: all)."""
        params = {"order": order}
        if state is not None:
            params["state"] = state
        if label is not None:
            params["label"] = label
        if cursor is not None:
            params["cursor"] = cursor
        count = 0
        while limit is None or count < limit:
            params["limit"] = _LIST_PAGE if limit is None else min(_LIST_PAGE, limit - count)
            page = self.call("job.list", params)
            for j in page.get("jobs") or []:
                count += 1
                yield Job.from_json(j)
            cursor = page.get("next_cursor")
            if cursor is None:
                return
            params["cursor"] = cursor

    def list(self, state=None, label=None, limit=None, order="oldest"):
        """job.list over all its pages: a list of Jobs (see iter_jobs)."""
        return [j for j in self.iter_jobs(state=state, label=label, limit=limit, order=order)]

    def export(self, job_id, path, density=None, node_mass=None, dead_fraction=None,
               drop_dead=False, sofa_version=None, case=None, dynamic=False,
               rayleigh_stiffness=None, rayleigh_mass=None, dt=None, gravity=None):
        """Writes a finished job's model with `springfit export ID -o PATH` (format by the
        extension: .vtu, .vtk, .msh, .scn, .json; proto/MODEL.md); returns path. The options
        are the command's, by the same names (proto/MODEL.md): `density` (mass per volume
        lumped on the FEM mesh's nodes) or `node_mass`, `dead_fraction` and `drop_dead`; for a
        .scn, `sofa_version` ("v24.06"), `case` (the load case's name), `dynamic`,
        `rayleigh_stiffness`, `rayleigh_mass`, `dt` and `gravity` (2 or 3 numbers). Raises
        CliError when springfit fails (e.g. exit 4: no such job, 9: no result yet, 2: a bad
        option, named in its stderr)."""
        args = ["export", str(int(job_id)), "-o", os.fspath(path)]
        for flag, value in (("--density", density), ("--node-mass", node_mass),
                            ("--dead-fraction", dead_fraction), ("--sofa-version", sofa_version),
                            ("--case", case), ("--rayleigh-stiffness", rayleigh_stiffness),
                            ("--rayleigh-mass", rayleigh_mass), ("--dt", dt)):
            if value is not None:
                args += [flag, value if isinstance(value, str) else f"{value:.17g}"]
        if gravity is not None:
            args += ["--gravity", ",".join(f"{float(g):.17g}" for g in gravity)]
        if drop_dead:
            args.append("--drop-dead")
        if dynamic:
            args.append("--dynamic")
        self._run_springfit(args, server=True)
        return path

    def _run_springfit(self, args, server):
        """Runs the springfit program; its stdout. With server, it talks to this Client's
        server with its token (through the environment: never on a command line)."""
        env = {k: v for k, v in os.environ.items() if not k.startswith("SPRINGFIT_")}
        command = [self.springfit] + list(args)
        if server:
            command += ["--server", f"{self.server}", "--timeout", f"{self.timeout:g}"]
            if self._token is not None:
                env["SPRINGFIT_TOKEN"] = self._token
        try:
            p = subprocess.run(command, stdin=subprocess.DEVNULL, capture_output=True, env=env)
        except OSError as e:
            raise CliError(command, 127, f"cannot run {self.springfit}: {e.strerror or e}") \
                from None
        if p.returncode != 0:
            raise CliError(command, p.returncode, p.stderr.decode("utf-8", "replace"))
        return p.stdout.decode("utf-8")
