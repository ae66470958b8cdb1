"""The shared part of the validation of springfit's FEM reference models against CalculiX
(ccx_self_check_test.py, ccx_traction_check_test.py and ccx_scenes_test.py).

The ccx harness imported (import_harness: tests/fem/ccx_reference.py), the tally of
comparisons and checks (Tally), the relative difference of two configurations (rel_diff),
structured meshes of triangles and tetrahedra (grid_nodes, grid_triangles, block_nodes,
block_tets), and run, which parses a test script's arguments (SPRINGFIT_BINARY
PROJECT_SOURCE_DIR [--keep DIR]), checks for the tools it needs, runs its checks and prints
`N passed, M failed`. Python 3 standard library only.
"""

import argparse
import math
import os
import shutil
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))

MISSING_TOOL = "{tool} not found: run scripts/install-deps.sh"


def import_harness(source_dir):
    """The ccx_reference module, from SOURCE_DIR/tests/fem, else from this directory."""
    for d in ([os.path.join(source_dir, "tests", "fem")] if source_dir else []) + [HERE]:
        if os.path.isfile(os.path.join(d, "ccx_reference.py")):
            sys.path.insert(0, d)
            break
    import ccx_reference
    return ccx_reference


# ----------------------------------------------------------------------------------------
# Reporting


class Tally:
    def __init__(self):
        self.passed = 0
        self.failed = 0

    def line(self, label, diff, tol, note=""):
        ok = diff is not None and math.isfinite(diff) and diff <= tol
        shown = "n/a" if diff is None else f"{diff:.3e}"
        print(f"{label}: max rel diff = {shown} (tol {tol:g}) {'OK' if ok else 'FAIL'}"
              f"{note}", flush=True)
        if ok:
            self.passed += 1
        else:
            self.failed += 1
        return ok

    def fail(self, label, why):
        print(f"{label}: FAIL ({why})", flush=True)
        self.failed += 1

    def check(self, label, ok, detail=""):
        if ok:
            print(f"{label}: OK{detail and '  (' + detail + ')'}", flush=True)
            self.passed += 1
        else:
            self.fail(label, detail)


def rel_diff(got, ref, rest):
    """max_i |got_i - ref_i| / max_i |ref_i - rest_i| over the nodes of one load case."""
    if len(got) != len(ref):
        return None
    scale = max(math.dist(r, x) for r, x in zip(ref, rest))
    if scale == 0.0:
        return None
    worst = 0.0
    for g, r in zip(got, ref):
        if len(g) != len(r) or not all(isinstance(c, (int, float)) for c in g):
            return None
        worst = max(worst, math.dist(g, r))
    return worst / scale


# ----------------------------------------------------------------------------------------
# Meshes


def grid_nodes(nx, ny, dx=1.0, dy=1.0, perturb=None):
    """(nx+1) x (ny+1) nodes, row by row from the bottom; perturb(i, j) -> (ox, oy) moves
    interior nodes."""
    nodes = []
    for j in range(ny + 1):
        for i in range(nx + 1):
            x, y = i * dx, j * dy
            if perturb and 0 < i < nx and 0 < j < ny:
                ox, oy = perturb(i, j)
                x, y = x + ox, y + oy
            nodes.append([x, y])
    return nodes


def grid_triangles(nx, ny, alternate=True):
    """Each cell split into two triangles; diagonals alternate in a checkerboard."""
    tris = []
    for j in range(ny):
        for i in range(nx):
            a = j * (nx + 1) + i
            b, c, d = a + 1, a + nx + 2, a + nx + 1
            if not alternate or (i + j) % 2 == 0:
                tris += [[a, b, c], [a, c, d]]
            else:
                tris += [[a, b, d], [b, c, d]]
    return tris


def block_nodes(nx, ny, nz, h=1.0, perturb=None):
    nodes = []
    for k in range(nz + 1):
        for j in range(ny + 1):
            for i in range(nx + 1):
                p = [i * h, j * h, k * h]
                if perturb and 0 < i < nx and 0 < j < ny and 0 < k < nz:
                    p = [c + o for c, o in zip(p, perturb(i, j, k))]
                nodes.append(p)
    return nodes


def block_tets(nx, ny, nz):
    """Each cube cell split into 6 tetrahedra around its main diagonal (Kuhn), which is the
    same in every cell, so neighbouring cells share face diagonals (a conforming mesh)."""
    def nid(i, j, k):
        return (k * (ny + 1) + j) * (nx + 1) + i

    paths = [(0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)]
    tets = []
    for k in range(nz):
        for j in range(ny):
            for i in range(nx):
                for path in paths:
                    c = [i, j, k]
                    tet = [nid(*c)]
                    for axis in path:
                        c[axis] += 1
                        tet.append(nid(*c))
                    tets.append(tet)
    return tets


# ----------------------------------------------------------------------------------------
# Running a test script


def run(argv, description, checks, tools, needs_springfit=False):
    """Parses a test script's arguments, imports the harness and runs checks(tally, args, tmp,
    harness) (tmp: a scratch directory, or --keep's, kept); returns the exit status: 0 when
    every check passed, 1 when one failed or a tool (a name in `tools`: "ccx (CalculiX)",
    "gmsh") is missing, 2 on bad usage (SPRINGFIT_BINARY and PROJECT_SOURCE_DIR are needed
    when needs_springfit)."""
    name = os.path.basename(sys.argv[0])
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("springfit", nargs="?", help="the springfit binary")
    ap.add_argument("source_dir", nargs="?", help="the project's source directory")
    ap.add_argument("--keep", metavar="DIR", help="write scenes and ccx decks here and keep them")
    args = ap.parse_args(argv)
    if needs_springfit and (not args.springfit or not args.source_dir):
        ap.print_usage(sys.stderr)
        print(f"{name}: SPRINGFIT_BINARY and PROJECT_SOURCE_DIR are required", file=sys.stderr)
        return 2
    harness = import_harness(args.source_dir)
    executables = {"ccx (CalculiX)": os.environ.get("CCX", "ccx"), "gmsh": "gmsh"}
    missing = [t for t in tools if not shutil.which(executables[t])]
    if missing:
        for t in missing:
            print(MISSING_TOOL.format(tool=t), file=sys.stderr)
        return 1
    if needs_springfit and not os.path.isfile(args.springfit):
        print(f"{name}: no springfit binary at {args.springfit}", file=sys.stderr)
        return 2

    start = time.monotonic()
    tally = Tally()
    tmp = args.keep or tempfile.mkdtemp(prefix="ccx_validation_")
    os.makedirs(tmp, exist_ok=True)
    try:
        checks(tally, args, tmp, harness)
    finally:
        if not args.keep:
            shutil.rmtree(tmp, ignore_errors=True)
    print(f"({time.monotonic() - start:.1f} s)")
    print(f"{tally.passed} passed, {tally.failed} failed")
    return 1 if tally.failed else 0
