"""The shared part of the tests of the Python client library (python/springfit_client) against a
real springfitd (client_library_package_test.py, client_library_errors_test.py and
client_library_jobs_test.py).

Their timeouts and token, the Context (the daemon, its token file, a scratch directory, long
jobs cancelled at the end; ctx.client() a Client of that daemon), clean_env, RpcErrors checked
(expect_rpc_error), the setup group (springfit_client imported from SOURCE_DIR/python, the
example scenes written, springfitd started with a token file), and run_groups, which runs a
script's groups, each bounded in time (harness.run_suite). Puts tests/daemon, where harness.py
is, on sys.path. Python 3 standard library only.
"""

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "daemon"))
from harness import STOP_TIMEOUT, Abort, Daemon, R, require, run_suite, short  # noqa: E402

CLIENT_TIMEOUT = 10.0     # the Client's timeout: to connect and for each answer
GROUP_TIMEOUT = 180       # for one group: a library that hangs fails the group, not the run
TOKEN = "0123456789abcdefABCDEF0123456789"

sf = None   # the springfit_client module, imported from SOURCE_DIR/python in setup


# --------------------------------------------------------------------------------------------
# The context


class Context:
    def __init__(self, springfitd, springfit, source):
        self.springfitd = springfitd
        self.springfit = springfit
        self.source = source
        self.tmp = tempfile.mkdtemp(prefix="springfit-pyclient-test-")
        self.daemons = []
        self.main = None
        self.token_file = os.path.join(self.tmp, "token")
        self.nonce = f"{os.getpid()}-{time.time_ns()}"
        self.iso_path = os.path.join(self.tmp, "paper-iso-5x5.json")
        self.kidney_path = os.path.join(self.tmp, "kidney-2d.json")
        self.long_jobs = []   # cancelled at cleanup if still running
        self.finished_job = None   # (job id, Job) of the round trip

    def server(self):
        return f"127.0.0.1:{self.main.port}"

    def client(self, **kwargs):
        kwargs.setdefault("token_file", self.token_file)
        kwargs.setdefault("timeout", CLIENT_TIMEOUT)
        kwargs.setdefault("springfit", self.springfit)
        return sf.Client(self.server(), **kwargs)

    def cleanup(self):
        R.current = "cleanup"
        if self.main is not None and self.main.alive() and self.long_jobs:
            try:
                with self.client() as c:
                    for job_id in self.long_jobs:
                        try:
                            c.cancel(job_id)
                        except sf.RpcError:
                            pass
            except (OSError, sf.SpringfitError):
                pass
        for d in self.daemons:
            if d.alive():
                R.expect(d.stop(), f"daemon {d.name} did not exit within {STOP_TIMEOUT}s of SIGTERM")
            else:
                d.close_files()
        shutil.rmtree(self.tmp, ignore_errors=True)


def clean_env(**extra):
    env = {k: v for k, v in os.environ.items() if not k.startswith("SPRINGFIT_")}
    env.update(extra)
    return env


def expect_rpc_error(what, code, fn, *args, **kwargs):
    """Calls fn, which must raise RpcError with `code`; returns the error (or None)."""
    try:
        value = fn(*args, **kwargs)
    except sf.RpcError as e:
        R.expect(e.code == code, f"{what}: RpcError code {e.code}, expected {code}: {e}")
        R.expect(isinstance(e.message, str) and e.message, f"{what}: RpcError without a message")
        R.expect(isinstance(e.data, dict), f"{what}: RpcError.data is {type(e.data).__name__}")
        return e
    except Exception as e:  # reported, not raised: the group goes on
        R.fail(f"{what}: expected RpcError {code}, got {type(e).__name__}: {e}")
        return None
    R.fail(f"{what}: expected RpcError {code}, got the answer {short(value)}")
    return None


# --------------------------------------------------------------------------------------------
# The setup group, and groups bounded in time


def test_setup(ctx):
    global sf
    for name in [k for k in os.environ if k.startswith("SPRINGFIT_")]:
        del os.environ[name]   # the Client's defaults: none from the caller's environment
    sys.path.insert(0, os.path.join(ctx.source, "python"))
    import springfit_client
    sf = springfit_client
    require(os.path.dirname(os.path.abspath(sf.__file__)) ==
            os.path.join(os.path.abspath(ctx.source), "python", "springfit_client"),
            f"springfit_client imported from {sf.__file__}, not from {ctx.source}/python")
    with open(ctx.token_file, "w") as f:
        f.write(TOKEN + "\n")
    os.chmod(ctx.token_file, 0o600)
    for name, path in (("paper-iso-5x5", ctx.iso_path), ("kidney-2d", ctx.kidney_path)):
        p = subprocess.run([ctx.springfit, "example", name, "-o", path], capture_output=True,
                           timeout=30, env=clean_env())
        require(p.returncode == 0, f"springfit example {name}: exit {p.returncode}: {p.stderr!r}")
    d = Daemon(ctx.springfitd, ctx.tmp, "main", ["--token-file", ctx.token_file])
    ctx.daemons.append(d)
    ctx.main = d.start()
    return sf  # (the test scripts' sf too)


def bounded(fn):
    """fn(ctx), aborted by SIGALRM after GROUP_TIMEOUT seconds (a blocking read included)."""
    def run(ctx):
        def expired(signum, frame):
            raise Abort(f"the group did not finish within {GROUP_TIMEOUT} s")
        previous = signal.signal(signal.SIGALRM, expired)
        signal.alarm(GROUP_TIMEOUT)
        try:
            fn(ctx)
        finally:
            signal.alarm(0)
            signal.signal(signal.SIGALRM, previous)
    return run


def run_groups(argv, doc, groups):
    """Runs a test script's groups (harness.run_suite) with this Context, each bounded by
    GROUP_TIMEOUT; doc is the script's docstring, whose second paragraph is its usage."""
    groups = [(name, bounded(fn), essential) for name, fn, essential in groups]
    return run_suite(argv, doc.strip().split("\n\n")[1], Context, groups,
                     lambda daemon: daemon.log_text())
