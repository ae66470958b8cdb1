#!/usr/bin/env python3
"""Independent FEM reference answers for springfit scenes, computed with CalculiX (ccx).

Usage: ccx_reference.py SCENE.json [-o OUT.json] [--workdir DIR] [--ccx PATH]

Reads a scene whose reference is {"type": "fem", ...} (proto/SCENE.md), writes one CalculiX
input deck per load case (every case starts from the rest state), runs `ccx` on each, reads
the nodal displacements from the .dat file (*NODE PRINT) and writes

    {"reference": {"type": "positions", "positions": [[[x, y], ...], ...]},
     "solves": [{"name": ..., "increments": I, "iterations": N, "cutbacks": C}, ...]}

where positions[k][i] is node i's equilibrium position under load case k. Only `reference`
has the form of the member of that name in what `springfit reference SCENE --json` prints
(compare those two); springfit's output also has `load_cases` (the scene's load cases with
tractions resolved into nodal forces), which this harness does not write, and its `solves`
hold springfit's own solver statistics (iterations, load_steps, residual, max_displacement),
while here `solves` holds ccx's (increments, Newton iterations and cutbacks read from the
.sta file). Python 3 standard library only.

How the scene maps onto CalculiX:
- 3D: C3D4 tetrahedra, isotropic *ELASTIC.
- 2D plane strain: CPE3 triangles, isotropic *ELASTIC, *SOLID SECTION with the thickness.
- 2D plane stress: CPE3 triangles with an orthotropic material (*ELASTIC, TYPE=ORTHO) whose
  in-plane constants are the plane-stress ones (D1111 = D2222 = E/(1-nu^2),
  D1122 = nu E/(1-nu^2), D1212 = E/(2(1+nu))) and no in-plane coupling to zz
  (D1133 = D2233 = 0). The plane-strain kinematics (E33 = E13 = E23 = 0) then give exactly the
  2D plane-stress law, linear or St. Venant-Kirchhoff (S = D : E under NLGEOM). CPS3 is not
  used: ccx expands it into wedges whose thickness varies from node to node, which is not the
  2D plane-stress law (exact on a homogeneous patch, but on the 5x5 plate sheared at
  nu = 0.45 it is 1e-2 off the 2D answer, where this construction agrees to 1e-7).
- material "linear": a linear *STATIC step; "st_venant_kirchhoff": *STEP, NLGEOM (ccx's
  *ELASTIC under NLGEOM is S = D : E with S the 2nd Piola-Kirchhoff stress and E the
  Green-Lagrange strain) with tight *CONTROLS; "neo_hookean" is refused.
- Nodes are 1-based in ccx (node i -> i + 1); elements are reordered to positive orientation.
- Fixed nodes: *BOUNDARY on every component; prescribed displacements: *BOUNDARY with the
  value; forces: *CLOAD (dead loads; forces on one node add up; in 2D the force acts on the
  whole thickness).
- Tractions (proto/SCENE.md, "Tractions"), resolved here from their definition into *CLOAD
  nodal forces: a traction acts on the boundary facets of the mesh (edges of triangles in 2D,
  triangular faces of tetrahedra in 3D, each belonging to exactly one element) whose nodes
  all belong to the node set `on`. A constant traction t on a linear facet of measure A
  (length in 2D, area in 3D, at rest) puts the consistent nodal force t A / d on each of its
  d nodes; `per_length` (2D; acting on the whole thickness, not multiplied by it) and
  `per_area` (3D) give t, `total` gives T spread as t = T / (the selected facets' summed
  measure). Shares that fall on a node constrained in the case (fixed or displaced) are
  dropped (the support takes them); the rest add to the case's `forces` (dead loads).
- A load case with a field other than name, fixed, displacements, forces and tractions, or an
  entry with an unknown field, is refused (exit 2): nothing that could change the mechanics is
  silently ignored.

The harness's parts: ccx_problem.py (the FEM problem), ccx_scene.py (reading the scene,
resolving tractions), ccx_deck.py (writing the decks) and ccx_run.py (running ccx, reading its
output); this file solves a problem with them and is the command.

Exit status: 0 on success, 1 when ccx fails (its message is printed), 2 on an invalid scene
or usage, 3 when ccx is not installed.
"""

import argparse
import json
import math
import os
import shutil
import sys
import tempfile

from ccx_deck import write_deck
# (Material, LoadCase, Problem and SceneError are the harness's API too: the tests build problems.)
from ccx_problem import LoadCase, Material, Problem, SceneError
from ccx_run import CcxError, CcxMissing, find_ccx, parse_dat, parse_sta, run_ccx
from ccx_scene import problem_from_scene

__all__ = ["CcxError", "CcxMissing", "LoadCase", "Material", "Problem", "SceneError",
           "problem_from_scene", "solve", "solve_scene", "main"]


# ----------------------------------------------------------------------------------------
# Solving


def solve(problem, workdir=None, ccx=None):
    """Solves every load case with ccx. Returns (positions, info): positions[k][i] is node i's
    position (dim components) under case k; info[k] a dict of ccx statistics."""
    ccx_path = find_ccx(ccx)
    problem.nonlinear()  # refuses unsupported models early
    used = sorted({i for e in problem.elements for i in e})
    used_set = set(used)
    for k, case in enumerate(problem.cases):
        for i in case.forces:
            if i not in used_set:
                raise SceneError(f"load_cases[{k}]: node {i} carries a force but belongs to no "
                                 f"element")
    own_tmp = workdir is None
    wd = tempfile.mkdtemp(prefix="ccx_reference_") if own_tmp else workdir
    os.makedirs(wd, exist_ok=True)
    try:
        positions, info = [], []
        for k, case in enumerate(problem.cases):
            job = f"case_{k:02d}"
            with open(os.path.join(wd, job + ".inp"), "w") as f:
                f.write(write_deck(problem, k, used))
            _, dat, sta = run_ccx(wd, job, ccx_path)
            time_, disp = parse_dat(dat)
            if abs(time_ - 1.0) > 1e-6:
                raise CcxError(f"{job}: the last displacement table is at time {time_}, not at "
                               f"the end of the step (1.0)")
            extent = max(math.dist(p, problem.nodes[0]) for p in problem.nodes)
            umax = max((math.sqrt(sum(c * c for c in u)) for u in disp.values()), default=0.0)
            if not umax < 1e3 * extent:
                raise CcxError(f"{job}: ccx returned displacements of {umax:.3g}, "
                               f"{umax / extent:.3g} times the model's size: its stiffness is "
                               f"singular (rigid motion or a mechanism left free?)")
            pos = []
            for i, p in enumerate(problem.nodes):
                if i in used_set:
                    u = disp.get(i + 1)
                    if u is None:
                        raise CcxError(f"{job}: no displacement for node {i} (ccx node {i + 1})")
                    if not all(math.isfinite(c) for c in u):
                        raise CcxError(f"{job}: non-finite displacement for node {i}")
                    u = list(u[:problem.dim])
                else:
                    u = [0.0] * problem.dim
                for d, v in case.constraints.get(i, {}).items():
                    u[d] = v  # exact prescribed value (the .dat carries 7 digits)
                pos.append([p[d] + u[d] for d in range(problem.dim)])
            positions.append(pos)
            incs, its, cuts = parse_sta(sta)
            info.append({"name": case.name, "increments": incs, "iterations": its,
                         "cutbacks": cuts})
        return positions, info
    finally:
        if own_tmp:
            shutil.rmtree(wd, ignore_errors=True)


def solve_scene(scene, workdir=None, ccx=None):
    """The harness's answer for a parsed scene: {"reference": positions reference in the form
    of springfit's `reference` (`springfit reference SCENE --json`), "solves": ccx's
    statistics per load case} (see the module docstring)."""
    problem = problem_from_scene(scene)
    positions, info = solve(problem, workdir, ccx)
    return {"reference": {"type": "positions", "positions": positions}, "solves": info}


def main(argv=None):
    ap = argparse.ArgumentParser(description="Solve a springfit FEM scene with CalculiX.")
    ap.add_argument("scene", help="scene JSON with a reference of type fem")
    ap.add_argument("-o", "--output", default="-", help="output JSON (default: stdout)")
    ap.add_argument("--workdir", help="keep the decks and ccx output here")
    ap.add_argument("--ccx", help="ccx executable (default: ccx on PATH, or $CCX)")
    args = ap.parse_args(argv)
    try:
        with open(args.scene) as f:
            scene = json.load(f)
    except (OSError, ValueError) as e:
        print(f"ccx_reference: {args.scene}: {e}", file=sys.stderr)
        return 2
    try:
        result = solve_scene(scene, args.workdir, args.ccx)
    except CcxMissing as e:
        print(str(e), file=sys.stderr)
        return 3
    except SceneError as e:
        print(f"ccx_reference: {args.scene}: {e}", file=sys.stderr)
        return 2
    except CcxError as e:
        print(f"ccx_reference: {args.scene}: {e}", file=sys.stderr)
        return 1
    text = json.dumps(result, indent=None, separators=(",", ":")) + "\n"
    if args.output == "-":
        sys.stdout.write(text)
    else:
        with open(args.output, "w") as f:
            f.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
