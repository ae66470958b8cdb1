"""The shared part of the end-to-end tests of the springfit client against springfitd
(client_jobs_test.py, client_auth_test.py, client_limits_test.py, client_store_test.py and
client_preparation_test.py).

Their timeouts and tokens, error answers checked (expect_error), a daemon that refuses to start
(run_refused_daemon), the Context (daemons in a temporary directory, stopped at the end),
springfit run with its exit code checked (run_cli, expect_exit, parse_json_output), the setup
group that starts the main daemon, and run_groups, which runs a script's groups
(harness.run_suite). Python 3 standard library only.
"""

import json
import os
import shutil
import subprocess
import tempfile
import time

from harness import STOP_TIMEOUT, Abort, Conn, Daemon, R, require, run_suite, short

# IO_TIMEOUT (5 s), START_TIMEOUT (10 s) and STOP_TIMEOUT (15 s) are harness.py's.
CLI_TIMEOUT = 20.0        # for one springfit invocation
JOB_TIMEOUT = 20.0        # for a small job to finish
REFUSE_TIMEOUT = 5.0      # for a daemon refusing its arguments to exit

TOKEN = "0123456789abcdefABCDEF0123456789"        # 32 characters
WRONG_TOKEN = "0123456789abcdefABCDEF012345678X"  # same length, last character differs
FINAL_STATES = ("succeeded", "failed", "cancelled")


# --------------------------------------------------------------------------------------------
# Error answers and a daemon that refuses to start


def expect_error(resp, code, what):
    """Checks that resp is an error response with `code`; returns its error object or {}."""
    ok = R.expect(isinstance(resp, dict) and isinstance(resp.get("error"), dict),
                  f"{what}: expected error {code}, got {short(resp)}")
    if not ok:
        return {}
    err = resp["error"]
    R.expect(err.get("code") == code, f"{what}: expected code {code}, got {err.get('code')}: {short(resp)}")
    R.expect(isinstance(err.get("message"), str) and err["message"],
             f"{what}: error without a message: {short(resp)}")
    return err


def run_refused_daemon(ctx, name, args, setup=None):
    """Starts springfitd with `args` (after its listen, database and port file), expecting it to
    refuse to start; setup runs in the child first (limits). Returns (exit code or None when it
    was still running after REFUSE_TIMEOUT, stderr, port file written)."""
    d = os.path.join(ctx.tmp, name)
    os.makedirs(d)
    err_path = os.path.join(d, "stderr")
    port_file = os.path.join(d, "port")
    with open(err_path, "wb") as err:
        proc = subprocess.Popen([ctx.springfitd, "--listen", "127.0.0.1:0", "--db", os.path.join(d, "test.db"),
                                 "--port-file", port_file] + list(args),
                                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err, preexec_fn=setup)
        try:
            code = proc.wait(REFUSE_TIMEOUT)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)
            code = None
    with open(err_path, "rb") as f:
        text = f.read().decode("utf-8", "replace")
    return code, text, os.path.exists(port_file)


# --------------------------------------------------------------------------------------------
# The context, springfit runs and the setup group


class Context:
    def __init__(self, springfitd, springfit, source):
        self.springfitd = springfitd
        self.springfit = springfit
        self.source = source
        self.tmp = tempfile.mkdtemp(prefix="springfit-client-test-")
        self.daemons = []
        self.iso_path = os.path.join(source, "examples", "paper-iso-5x5.json")
        self.aniso_path = os.path.join(source, "examples", "paper-aniso-5x5.json")
        self.kidney_path = os.path.join(source, "examples", "kidney-2d.json")
        self.plate_path = os.path.join(source, "examples", "fem-plate-5x5.json")
        with open(self.iso_path) as f:
            self.small_scene = json.load(f)
        self.nonce = f"{os.getpid()}-{time.time_ns()}"
        self.main = None
        self.token_daemon = None
        self.watch_proc = None
        self.long_job = None

    def daemon(self, name, extra=()):
        d = Daemon(self.springfitd, self.tmp, name, extra)
        self.daemons.append(d)
        return d.start()

    def server(self):
        return f"127.0.0.1:{self.main.port}"

    def cleanup(self):
        R.current = "cleanup"
        if self.watch_proc is not None and self.watch_proc.poll() is None:
            self.watch_proc.kill()
            self.watch_proc.wait(5)
        if self.long_job is not None and self.main is not None and self.main.alive():
            try:
                with Conn(self.main.port) as c:
                    c.call("job.cancel", {"job_id": self.long_job})
            except (OSError, Abort):
                pass
        for d in self.daemons:
            if d.alive():
                R.expect(d.stop(), f"daemon {d.name} did not exit within {STOP_TIMEOUT}s of SIGTERM")
            else:
                d.close_files()
        shutil.rmtree(self.tmp, ignore_errors=True)


def run_cli(ctx, *args, timeout=CLI_TIMEOUT):
    """Runs springfit; (exit code or None on timeout, stdout, stderr, wall seconds)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("SPRINGFIT_")}
    t0 = time.monotonic()
    try:
        p = subprocess.run([ctx.springfit] + list(args), stdin=subprocess.DEVNULL, capture_output=True,
                           timeout=timeout, env=env, cwd=ctx.source)
    except subprocess.TimeoutExpired:
        return None, "", "(timed out)", time.monotonic() - t0
    return (p.returncode, p.stdout.decode("utf-8", "replace"), p.stderr.decode("utf-8", "replace"),
            time.monotonic() - t0)


def cli_desc(args):
    return "springfit " + " ".join(args)


def expect_exit(ctx, want, *args):
    code, out, err, _ = run_cli(ctx, *args)
    R.expect(code == want, f"{cli_desc(args)}: exit {code}, expected {want} (stdout: {short(out)}; "
                           f"stderr: {short(err)})")
    return code, out, err


def parse_json_output(text, what):
    """stdout that must be exactly one JSON value; the value, or None (reported)."""
    try:
        return json.loads(text)
    except ValueError as e:
        R.fail(f"{what}: stdout is not exactly one JSON value ({e}): {short(text)}")
        return None


def test_setup(ctx):
    ctx.main = ctx.daemon("main")
    with Conn(ctx.main.port) as c:
        info = c.result("server.info")
        require(info.get("name") == "springfitd" and info.get("auth_required") is False,
                f"server.info: {short(info)}")


def run_groups(argv, doc, groups):
    """Runs a test script's groups (harness.run_suite) with this Context; doc is the script's
    docstring, whose second paragraph is its usage."""
    return run_suite(argv, doc.strip().split("\n\n")[1], Context, groups,
                     lambda daemon: daemon.log_text())
