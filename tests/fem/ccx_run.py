"""Running ccx and reading its output, for the ccx harness (ccx_reference.py): the executable
(find_ccx), a run on one deck (run_ccx), the last displacement table of its .dat file
(parse_dat) and the increments, iterations and cutbacks of its .sta file (parse_sta).
Python 3 standard library only.
"""

import os
import re
import shutil
import subprocess

CCX_MISSING = "ccx (CalculiX) not found: run scripts/install-deps.sh"
CCX_TIMEOUT = 300.0  # seconds for one ccx run


class CcxError(Exception):
    """ccx failed or its output could not be read."""


class CcxMissing(Exception):
    pass


def find_ccx(ccx=None):
    path = shutil.which(ccx or os.environ.get("CCX", "ccx"))
    if not path:
        raise CcxMissing(CCX_MISSING)
    return path


def ffloat(tok):
    """A Fortran-printed real: 1.5E-01, 1.5D-01, or 1.500000-100 (3-digit exponent)."""
    t = tok.replace("D", "E").replace("d", "E")
    try:
        return float(t)
    except ValueError:
        m = re.match(r"^([-+]?\d*\.\d*)([-+]\d+)$", t)
        if m:
            return float(m.group(1) + "E" + m.group(2))
        raise


def parse_dat(text, set_name="NALL"):
    """The last 'displacements ... for set NALL' block: (time, {node: (ux, uy, uz)})."""
    header = re.compile(r"^\s*displacements \(vx,vy,vz\) for set (\S+) and time\s+(\S+)")
    blocks = []
    current = None
    for line in text.splitlines():
        m = header.match(line)
        if m:
            current = None
            if m.group(1).upper() == set_name.upper():
                current = {}
                blocks.append((ffloat(m.group(2)), current))
            continue
        if current is None:
            continue
        parts = line.split()
        if not parts:
            if current:
                current = None
            continue
        if len(parts) == 4 and parts[0].isdigit():
            current[int(parts[0])] = tuple(ffloat(p) for p in parts[1:])
        else:
            current = None
    if not blocks:
        raise CcxError(f"no displacement table for set {set_name} in the .dat file")
    return blocks[-1]


def parse_sta(text):
    """(increments, iterations, cutbacks) from ccx's .sta file."""
    incs = its = cuts = 0
    for line in text.splitlines():
        parts = line.split()
        if len(parts) == 7 and all(p.isdigit() for p in parts[:4]):
            incs += 1
            cuts += int(parts[2]) - 1
            its += int(parts[3])
    return incs, its, cuts


def _ccx_messages(out):
    lines = out.splitlines()
    msgs = []
    for k, line in enumerate(lines):
        if "*ERROR" in line.upper():
            block = [line.strip()]
            for nxt in lines[k + 1:k + 4]:
                if not nxt.strip() or "*" in nxt:
                    break
                block.append(nxt.strip())
            msgs.append(" ".join(block))
    return msgs


def run_ccx(workdir, job, ccx_path):
    """Runs ccx on workdir/job.inp; returns (stdout text, .dat text, .sta text)."""
    env = dict(os.environ)
    env.update(OMP_NUM_THREADS="1", CCX_NPROC_STIFFNESS="1", CCX_NPROC_EQUATION_SOLVER="1",
               CCX_NPROC_RESULTS="1")
    try:
        proc = subprocess.run([ccx_path, "-i", job], cwd=workdir, env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              stdin=subprocess.DEVNULL, timeout=CCX_TIMEOUT)
    except subprocess.TimeoutExpired:
        raise CcxError(f"ccx on {job}.inp did not finish within {CCX_TIMEOUT:.0f} s")
    out = proc.stdout.decode("utf-8", "replace")
    msgs = _ccx_messages(out)
    if proc.returncode != 0 or msgs or "Job finished" not in out:
        detail = "; ".join(msgs) if msgs else "\n".join(out.strip().splitlines()[-8:])
        raise CcxError(f"ccx failed on {os.path.join(workdir, job)}.inp "
                       f"(exit {proc.returncode}): {detail}")
    dat = _read(os.path.join(workdir, job + ".dat"))
    sta = _read(os.path.join(workdir, job + ".sta"), missing_ok=True)
    return out, dat, sta


def _read(path, missing_ok=False):
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            return f.read()
    except FileNotFoundError:
        if missing_ok:
            return ""
        raise CcxError(f"ccx wrote no {os.path.basename(path)}")
