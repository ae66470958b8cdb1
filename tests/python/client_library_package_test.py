#!/usr/bin/env python3
"""The Python client library (python/springfit_client) as its users get it: installed by pip,
and README.md's example, against a real springfitd.

Usage: client_library_package_test.py SPRINGFITD SPRINGFIT SOURCE_DIR

Starts springfitd on 127.0.0.1 (a free port, SQLite in a temporary directory, a token file)
and checks: `pip install` of python/ offline into a plain venv (no setuptools, no wheel) and
the installed copy talking to the daemon; and runs README.md's "Python client" example
verbatim. Python 3 standard library only (the shared part: client_library_support.py).

Prints one line per check group (PASS/FAIL) and one FAIL line per failed check; exits 0 when
everything passed, 1 otherwise (2 on bad usage).
"""

import os
import re
import shutil
import subprocess
import sys

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
from client_library_support import TOKEN, clean_env, run_groups, test_setup  # noqa: E402
# (harness.py is in tests/daemon, which importing client_library_support puts on sys.path)
from harness import R, require, short  # noqa: E402

PIP_TIMEOUT = 120.0       # for venv and pip install
EXAMPLE_TIMEOUT = 60.0    # for README.md's example
DEBIAN_PYTHON = "/usr/bin/python3"   # Debian's, with python3-venv from install-deps.sh


def test_package(ctx):
    """pip install of python/ into a plain venv, offline (--no-index), with and without build
    isolation, in a venv from which setuptools and wheel are removed (Python 3.12's venvs have
    neither; an install that needed them failed there with "invalid command 'bdist_wheel'"):
    the project's own build backend needs nothing but pip. With Debian's python3 (python3-venv
    from install-deps.sh) and, where it is another one, the python3 running this test. The
    installed copy, run by the venv's python, talks to the daemon."""
    pythons = [DEBIAN_PYTHON] if os.access(DEBIAN_PYTHON, os.X_OK) else []
    if not pythons or os.path.realpath(sys.executable) != os.path.realpath(DEBIAN_PYTHON):
        pythons.append(sys.executable)
    env = clean_env(PIP_ROOT_USER_ACTION="ignore", PIP_DISABLE_PIP_VERSION_CHECK="1",
                    PYTHONDONTWRITEBYTECODE="1")
    src = os.path.join(ctx.source, "python")
    for n, python in enumerate(pythons):
        venv = os.path.join(ctx.tmp, f"venv{n}")
        p = subprocess.run([python, "-m", "venv", venv], capture_output=True, timeout=PIP_TIMEOUT)
        require(p.returncode == 0, f"{python} -m venv: exit {p.returncode} (run "
                                   f"scripts/install-deps.sh: python3-venv): {short(p.stderr.decode(), 600)}")
        vpy = os.path.join(venv, "bin", "python")
        pip = [vpy, "-m", "pip"]
        subprocess.run(pip + ["uninstall", "-y", "--quiet", "setuptools", "wheel"],
                       capture_output=True, timeout=PIP_TIMEOUT, env=env)
        probe = subprocess.run([vpy, "-c", "import setuptools"], capture_output=True, timeout=30)
        R.expect(probe.returncode != 0, f"{venv}: setuptools is still there: the venv is not plain")
        for isolation in ([], ["--no-build-isolation"]):
            subprocess.run(pip + ["uninstall", "-y", "--quiet", "springfit-client"],
                           capture_output=True, timeout=PIP_TIMEOUT, env=env)
            p = subprocess.run(pip + ["install", "--no-index", "--quiet", *isolation, src],
                               capture_output=True, timeout=PIP_TIMEOUT, env=env)
            R.expect(p.returncode == 0, f"{python}: pip install --no-index {' '.join(isolation)} "
                                        f"./python in a plain venv: exit {p.returncode}: "
                                        f"{short(p.stderr.decode(), 1500)}")
        # The installed copy (not the source tree), by the name pip knows it, against the daemon.
        code = ("import sys, importlib.metadata as m, springfit_client as s\n"
                "assert s.__file__.startswith(sys.prefix), s.__file__\n"
                "files = {f.name for f in m.files('springfit-client')}\n"
                "assert {'__init__.py', 'client.py', 'py.typed'} <= files, files\n"
                "with s.Client(sys.argv[1], token_file=sys.argv[2], timeout=10) as c:\n"
                "    print(m.version('springfit-client'), c.info().name, c.info().auth_required)\n")
        p = subprocess.run([vpy, "-c", code, ctx.server(), ctx.token_file],
                           capture_output=True, timeout=60, env=env, cwd=ctx.tmp)
        R.expect(p.returncode == 0 and p.stdout.decode().split() == ["1.0.0", "springfitd", "True"],
                 f"{python}: the venv's package against the daemon: exit {p.returncode}, stdout "
                 f"{p.stdout.decode()!r}, stderr {short(p.stderr.decode(), 800)}")


def readme_example(source):
    """The code block between README.md's python-client markers."""
    with open(os.path.join(source, "README.md"), encoding="utf-8") as f:
        text = f.read()
    m = re.search(r"<!-- python-client -->\s*```python\n(.*?)```\s*<!-- /python-client -->", text, re.S)
    require(m, "README.md has no ```python block between <!-- python-client --> markers")
    return m.group(1)


def test_readme_example(ctx):
    code = readme_example(ctx.source)
    work = os.path.join(ctx.tmp, "readme")
    os.makedirs(os.path.join(work, "examples"))
    shutil.copy(os.path.join(ctx.source, "examples", "paper-iso-5x5.json"), os.path.join(work, "examples"))
    env = clean_env(SPRINGFIT_SERVER=ctx.server(), SPRINGFIT_TOKEN=TOKEN,
                    PYTHONPATH=os.path.join(ctx.source, "python"), PYTHONDONTWRITEBYTECODE="1",
                    PATH=os.path.dirname(ctx.springfit) + os.pathsep + os.environ.get("PATH", ""))
    p = subprocess.run([sys.executable, "-c", code], cwd=work, capture_output=True,
                       timeout=EXAMPLE_TIMEOUT, env=env)
    out, err = p.stdout.decode(), p.stderr.decode()
    R.expect(p.returncode == 0, f"README's example: exit {p.returncode}: {short(err, 1500)}")
    m = re.search(r"^job (\d+) succeeded, verdict usable: E 0\b", out, re.M)
    R.expect(m, f"README's example: no 'job N succeeded, verdict usable: E 0' line: {out!r}")
    R.expect(re.search(r"^job \d+: generation 0/1000, E ", out, re.M),
             f"README's example printed no progress: {out!r}")
    R.expect("72 springs, recovered exactly: True" in out, f"README's example: {out!r}")
    R.expect("cancel: " in out and "(-32006)" in out, f"README's example's cancel: {out!r}")
    vtu = os.path.join(work, "model.vtu")
    R.expect(os.path.isfile(vtu) and os.path.getsize(vtu) > 0, "README's example wrote no model.vtu")
    if m:
        with ctx.client() as c:
            job = c.status(int(m.group(1)))
            R.expect(job.label == "readme" and job.seed == 7, f"README's job: {job}")


if __name__ == "__main__":
    sys.exit(run_groups(sys.argv, __doc__, [
        ("setup", test_setup, True),
        ("pip install in a plain venv", test_package, False),
        ("README example", test_readme_example, False),
    ]))
