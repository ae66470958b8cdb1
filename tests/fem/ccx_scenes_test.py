#!/usr/bin/env python3
"""Validates springfit's FEM reference models against CalculiX (ccx), scene by scene.

Usage: ccx_scenes_test.py SPRINGFIT_BINARY PROJECT_SOURCE_DIR [--keep DIR]

Generates scenes (a 4-triangle patch, a 5x5 plate, a gmsh-meshed plate with an elliptical
hole, a tetrahedral block, their St. Venant-Kirchhoff versions, prescribed displacements, two
material regions, a distorted tetrahedral block under a per_area and a total traction) and
reads the committed examples loaded by tractions (examples/fem-plate-5x5.json, linear plane
stress; examples/fem-kidney-2d-nl.json, St. Venant-Kirchhoff plane strain), writes them to a
temporary directory, runs `SPRINGFIT_BINARY reference SCENE --json` and the ccx harness
(tests/fem/ccx_reference.py, itself checked by ccx_self_check_test.py and
ccx_traction_check_test.py) on each, and compares the positions: max over nodes of
|x_springfit - x_ccx| / max over nodes of |u_ccx| per load case. Tolerances: linear 1e-6 (ccx
prints 7 significant digits, so its answer carries up to 5e-7 of that), St. Venant-Kirchhoff
1e-4. On scenes with tractions it also compares the nodal forces springfit prints in its
resolved `load_cases` with the harness's (max |df| / max |f| over the scene's traction cases,
tolerance 1e-12).

Prints one line per comparison and ends with `N passed, M failed`; exits 1 if any failed
(or ccx / gmsh are missing), 2 on bad usage. Python 3 standard library only (the shared part:
ccx_validation_support.py).
"""

import json
import math
import os
import subprocess
import sys

from ccx_validation_support import (block_nodes, block_tets, grid_nodes, grid_triangles,
                                    rel_diff, run)

TOL_LINEAR = 1e-6
TOL_SVK = 1e-4
TOL_FORCES = 1e-12       # nodal forces of tractions: the same sums, to round-off
SPRINGFIT_TIMEOUT = 120.0

cr = None  # the ccx_reference module, imported by run()


def force_diff(got, want):
    """max_i |got_i - want_i| / max_i |want_i| over two {node: force vector} maps (a node
    missing from one counts as a zero force there); None when want is all zero."""
    scale = max((math.sqrt(sum(c * c for c in f)) for f in want.values()), default=0.0)
    if scale == 0.0:
        return None
    worst = 0.0
    for i in set(got) | set(want):
        g, w = got.get(i), want.get(i)
        dim = len(g if g is not None else w)
        g = g if g is not None else [0.0] * dim
        w = w if w is not None else [0.0] * dim
        if len(g) != len(w):
            return None
        worst = max(worst, math.dist(g, w))
    return worst / scale


# ----------------------------------------------------------------------------------------
# Meshes


def patch_mesh():
    """A unit square split into 4 triangles around a centre node (one written clockwise)."""
    nodes = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]]
    tris = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [0, 3, 4]]  # the last one is clockwise
    return nodes, tris


# ----------------------------------------------------------------------------------------
# gmsh


HOLE_GEO = """// a 4 x 2 plate with an elliptical hole (semi-axes 0.7, 0.4) at its centre
lc = 0.3;
lh = 0.15;
Point(1) = {0, 0, 0, lc};
Point(2) = {4, 0, 0, lc};
Point(3) = {4, 2, 0, lc};
Point(4) = {0, 2, 0, lc};
Point(5) = {2, 1, 0, lh};
Point(6) = {2.7, 1, 0, lh};
Point(7) = {2, 1.4, 0, lh};
Point(8) = {1.3, 1, 0, lh};
Point(9) = {2, 0.6, 0, lh};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Ellipse(5) = {6, 5, 6, 7};
Ellipse(6) = {7, 5, 6, 8};
Ellipse(7) = {8, 5, 6, 9};
Ellipse(8) = {9, 5, 6, 6};
Curve Loop(1) = {1, 2, 3, 4};
Curve Loop(2) = {5, 6, 7, 8};
Plane Surface(1) = {1, 2};
"""


def read_msh22(path):
    """An ASCII MSH 2.2 file: (nodes [[x, y]], triangles) keeping only the nodes of 3-node
    triangles (element type 2), renumbered from 0 in file order, z dropped."""
    with open(path) as f:
        lines = [ln.strip() for ln in f]
    k = 0
    raw_nodes, raw_tris = {}, []
    order = []
    while k < len(lines):
        tag = lines[k]
        if tag == "$MeshFormat":
            version, filetype = lines[k + 1].split()[:2]
            if not version.startswith("2.") or filetype != "0":
                raise ValueError(f"{path}: not an ASCII MSH 2.x file ({lines[k + 1]})")
            k += 2
        elif tag == "$Nodes":
            n = int(lines[k + 1])
            for ln in lines[k + 2:k + 2 + n]:
                parts = ln.split()
                raw_nodes[int(parts[0])] = [float(parts[1]), float(parts[2])]
                order.append(int(parts[0]))
            k += 2 + n
        elif tag == "$Elements":
            n = int(lines[k + 1])
            for ln in lines[k + 2:k + 2 + n]:
                parts = [int(p) for p in ln.split()]
                etype, ntags = parts[1], parts[2]
                if etype == 2:
                    raw_tris.append(parts[3 + ntags:3 + ntags + 3])
            k += 2 + n
        else:
            k += 1
    used = {i for t in raw_tris for i in t}
    index = {}
    nodes = []
    for i in order:
        if i in used:
            index[i] = len(nodes)
            nodes.append(raw_nodes[i])
    return nodes, [[index[i] for i in t] for t in raw_tris]


def gmsh_hole_mesh(tmp):
    geo = os.path.join(tmp, "hole.geo")
    msh = os.path.join(tmp, "hole.msh")
    with open(geo, "w") as f:
        f.write(HOLE_GEO)
    proc = subprocess.run(["gmsh", "-2", "-format", "msh22", geo, "-o", msh],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=120)
    if proc.returncode != 0 or not os.path.isfile(msh):
        raise RuntimeError("gmsh failed: " + proc.stdout.decode("utf-8", "replace")[-2000:])
    return read_msh22(msh)


# ----------------------------------------------------------------------------------------
# Scenes


def fem(elements, material=None, plane=None, thickness=None, materials=None, ids=None):
    ref = {"type": "fem", "elements": elements}
    if materials is not None:
        ref["materials"] = materials
        ref["element_materials"] = ids
    else:
        ref["material"] = material
    if plane is not None:
        ref["plane"] = plane
    if thickness is not None:
        ref["thickness"] = thickness
    return ref


def scene(name, nodes, reference, cases):
    # "nearest" candidates work for any node set (the gmsh mesh is on no lattice)
    return {"name": name, "nodes": nodes, "candidates": {"type": "nearest", "k": 8},
            "reference": reference, "load_cases": cases}


def mat(model, young, poisson):
    return {"model": model, "young": young, "poisson": poisson}


def make_scenes(tmp, source_dir):
    """[(scene dict, tolerance)]"""
    out = []
    # The patch: stretched along x, then along y.
    nodes, tris = patch_mesh()
    patch_cases = [
        {"name": "stretch x", "fixed": [0, 3],
         "forces": [{"nodes": [1, 2], "force": [0.05, 0.0]}]},
        {"name": "stretch y", "fixed": [0, 1],
         "forces": [{"node": 2, "force": [0.0, 0.05]}, {"node": 3, "force": [0.0, 0.05]},
                    {"node": 3, "force": [0.01, 0.0]}]},
    ]
    out.append((scene("patch-plane-stress", nodes,
                      fem(tris, mat("linear", 10.0, 0.3), "stress"), patch_cases), TOL_LINEAR))
    out.append((scene("patch-plane-strain", nodes,
                      fem(tris, mat("linear", 10.0, 0.45), "strain"), patch_cases), TOL_LINEAR))

    # The 5x5 plate (unit spacing, thickness 0.1): bottom row fixed, top row loaded.
    nodes = grid_nodes(4, 4)
    tris = grid_triangles(4, 4)
    bottom, top = [0, 1, 2, 3, 4], [20, 21, 22, 23, 24]
    plate_cases = [
        {"name": "stretch", "fixed": bottom, "forces": [{"nodes": top, "force": [0.0, 0.01]}]},
        {"name": "shear", "fixed": bottom, "forces": [{"nodes": top, "force": [0.01, 0.0]}]},
        {"name": "displaced top", "fixed": bottom,
         "displacements": [{"nodes": top, "displacement": [0.05, 0.02]}],
         "forces": [{"node": 12, "force": [0.0, -0.005]}]},
    ]
    out.append((scene("plate-5x5", nodes, fem(tris, mat("linear", 10.0, 0.3), "stress", 0.1),
                      plate_cases), TOL_LINEAR))
    # ... St. Venant-Kirchhoff at 5-10% strain: nominal stress ~0.7 = 7% of E on the top.
    svk_cases = [
        {"name": "stretch", "fixed": bottom, "forces": [{"nodes": top, "force": [0.0, 0.06]}]},
        {"name": "shear", "fixed": bottom, "forces": [{"nodes": top, "force": [0.01, 0.0]}]},
        {"name": "displaced top", "fixed": bottom,
         "displacements": [{"nodes": top, "displacement": [0.25, 0.2]}]},
    ]
    out.append((scene("plate-5x5-svk", nodes,
                      fem(tris, mat("st_venant_kirchhoff", 10.0, 0.3), "stress", 0.1),
                      svk_cases), TOL_SVK))
    # ... two regions: left half E = 10, nu = 0.3; right half E = 40, nu = 0.4 (plane strain).
    ids = [0 if sum(nodes[i][0] for i in t) / 3 < 2.0 else 1 for t in tris]
    out.append((scene("plate-5x5-two-regions", nodes,
                      fem(tris, plane="strain", thickness=0.1,
                          materials=[mat("linear", 10.0, 0.3), mat("linear", 40.0, 0.4)],
                          ids=ids), plate_cases[:2]), TOL_LINEAR))

    # The gmsh plate with an elliptical hole, plane strain: left end fixed, right end loaded.
    nodes, tris = gmsh_hole_mesh(tmp)
    left = [i for i, p in enumerate(nodes) if abs(p[0]) < 1e-9]
    right = [i for i, p in enumerate(nodes) if abs(p[0] - 4.0) < 1e-9]
    per = 1.0 / len(right)
    out.append((scene(f"gmsh-hole-{len(nodes)}-nodes", nodes,
                      fem(tris, mat("linear", 10.0, 0.3), "strain"),
                      [{"name": "tension", "fixed": left,
                        "forces": [{"nodes": right, "force": [0.2 * per, 0.0]}]},
                       {"name": "bending", "fixed": left,
                        "forces": [{"nodes": right, "force": [0.0, -0.01 * per]}]}]),
                TOL_LINEAR))

    # The tetrahedral block: 4 x 3 x 3 nodes (unit spacing), 6 tets per cell; bottom fixed.
    nodes = block_nodes(3, 2, 2)
    tets = block_tets(3, 2, 2)
    bottom = [i for i, p in enumerate(nodes) if p[2] == 0.0]
    top = [i for i, p in enumerate(nodes) if p[2] == 2.0]
    out.append((scene("block-4x3x3", nodes, fem(tets, mat("linear", 10.0, 0.3)),
                      [{"name": "pull z", "fixed": bottom,
                        "forces": [{"nodes": top, "force": [0.0, 0.0, 0.05]}]},
                       {"name": "push x", "fixed": bottom,
                        "forces": [{"nodes": top, "force": [0.02, 0.0, 0.0]}]}]), TOL_LINEAR))
    # ... St. Venant-Kirchhoff: 12 top nodes x 0.3 over 6 = 0.6 nominal (~6% strain).
    out.append((scene("block-4x3x3-svk", nodes,
                      fem(tets, mat("st_venant_kirchhoff", 10.0, 0.3)),
                      [{"name": "pull z", "fixed": bottom,
                        "forces": [{"nodes": top, "force": [0.0, 0.0, 0.3]}]},
                       {"name": "push x", "fixed": bottom,
                        "forces": [{"nodes": top, "force": [0.1, 0.0, 0.0]}]},
                       {"name": "displaced top", "fixed": bottom,
                        "displacements": [{"nodes": top, "displacement": [0.1, 0.0, -0.15]}]}]),
                TOL_SVK))

    # Tractions. The same block, distorted so that its boundary triangles differ in area
    # (x -> x + 0.1 x^2, y -> y (1 + 0.1 x); the faces stay planar), bottom fixed: a per_area
    # traction on the top face, a total traction on the side x = max (whose bottom edge is
    # fixed, so the shares there go to the support), and both with a force on a top corner.
    nodes = [[x + 0.1 * x * x, y * (1.0 + 0.1 * x), z] for x, y, z in block_nodes(3, 2, 2)]
    sets = {"bottom": bottom, "top": top,
            "side": [i for i, p in enumerate(block_nodes(3, 2, 2)) if p[0] == 3.0]}
    top_load = {"on": "top", "per_area": [0.004, -0.002, 0.02]}
    side_load = {"on": "side", "total": [0.0, 0.06, 0.03]}
    sc = scene("block-4x3x3-tractions", nodes, fem(tets, mat("linear", 10.0, 0.3)),
               [{"name": "top per_area", "fixed": "bottom", "tractions": [top_load]},
                {"name": "side total", "fixed": "bottom", "tractions": [side_load]},
                {"name": "both and a force", "fixed": "bottom",
                 "forces": [{"node": top[-1], "force": [0.0, 0.0, 0.01]}],
                 "tractions": [top_load, side_load]}])
    sc["node_sets"] = sets
    out.append((sc, TOL_LINEAR))

    # The committed examples loaded by tractions (the paper's seven load cases at 5% strain).
    for example, tol in (("fem-plate-5x5.json", TOL_LINEAR),          # linear, plane stress
                         ("fem-kidney-2d-nl.json", TOL_SVK)):         # SVK, plane strain
        with open(os.path.join(source_dir, "examples", example)) as f:
            out.append((json.load(f), tol))
    return out


# ----------------------------------------------------------------------------------------
# springfit


def run_springfit(binary, path):
    """(positions, resolved load cases, None) or (None, None, why)."""
    try:
        proc = subprocess.run([binary, "reference", path, "--json"], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, stdin=subprocess.DEVNULL,
                              timeout=SPRINGFIT_TIMEOUT)
    except subprocess.TimeoutExpired:
        return None, None, f"springfit did not finish within {SPRINGFIT_TIMEOUT:.0f} s"
    except OSError as e:
        return None, None, f"cannot run {binary}: {e}"
    err = proc.stderr.decode("utf-8", "replace").strip()
    if proc.returncode != 0:
        return None, None, f"springfit exited {proc.returncode}: {err}"
    try:
        doc = json.loads(proc.stdout)
        ref = doc["reference"]
        if ref.get("type") != "positions":
            return None, None, f"springfit printed a reference of type {ref.get('type')!r}"
        return ref["positions"], doc.get("load_cases"), None
    except (ValueError, KeyError, TypeError, AttributeError) as e:
        return None, None, f"unreadable springfit output ({e}): {proc.stdout[:300]!r}"


def printed_forces(case, node_sets):
    """{node: force} from a load case as springfit prints it (forces summed per node)."""
    out = {}
    for entry in case.get("forces", []):
        targets = entry["nodes"] if "nodes" in entry else [entry["node"]]
        if isinstance(targets, str):
            targets = node_sets[targets]
        for i in targets:
            acc = out.setdefault(i, [0.0] * len(entry["force"]))
            for d, v in enumerate(entry["force"]):
                acc[d] += v
    return out


def compare_forces(tally, sc, printed):
    """springfit's nodal forces of the tractions (its resolved load_cases) against the
    harness's, over the scene's load cases that have tractions."""
    traction_cases = [k for k, c in enumerate(sc["load_cases"]) if c.get("tractions")]
    if not traction_cases:
        return
    label = (f"{sc['name']} nodal forces of the tractions ({len(traction_cases)} case"
             f"{'s' if len(traction_cases) > 1 else ''})")
    try:
        cases = cr.problem_from_scene(sc).cases
        if not isinstance(printed, list) or len(printed) != len(cases):
            raise ValueError(f"springfit printed {len(printed or [])} load cases for "
                             f"{len(cases)}")
        worst = 0.0
        for k in traction_cases:
            if printed[k].get("tractions"):
                raise ValueError(f"springfit's load_cases[{k}] still has tractions")
            d = force_diff(printed_forces(printed[k], sc.get("node_sets", {})),
                           cases[k].forces)
            if d is None:
                raise ValueError(f"load_cases[{k}]: no nodal forces to compare")
            worst = max(worst, d)
    except (cr.SceneError, ValueError, KeyError, TypeError, AttributeError) as e:
        tally.fail(label, str(e))
        return
    tally.line(label, worst, TOL_FORCES)


def compare_scenes(tally, binary, tmp, source_dir):
    print("== springfit reference against ccx", flush=True)
    for sc, tol in make_scenes(tmp, source_dir):
        name = sc["name"]
        path = os.path.join(tmp, name + ".json")
        with open(path, "w") as f:
            json.dump(sc, f)
        labels = [f"{name} {c['name']}" for c in sc["load_cases"]]
        try:
            expected = cr.solve_scene(sc, os.path.join(tmp, "ccx-" + name))
        except (cr.CcxError, cr.SceneError) as e:
            for label in labels:
                tally.fail(label, f"ccx harness: {e}")
            continue
        got, printed, why = run_springfit(binary, path)
        if got is None:
            for label in labels:
                tally.fail(label, why)
            continue
        if not isinstance(got, list) or len(got) != len(labels):
            for label in labels:
                tally.fail(label, f"springfit printed {len(got) if isinstance(got, list) else 0}"
                                  f" configurations for {len(labels)} load cases")
            continue
        for k, label in enumerate(labels):
            ref = expected["reference"]["positions"][k]
            d = rel_diff(got[k], ref, sc["nodes"])
            note = "" if d is not None else "  (springfit's positions do not match the scene)"
            tally.line(label, d, tol, note)
        compare_forces(tally, sc, printed)




def checks(tally, args, tmp, harness):
    global cr
    cr = harness
    compare_scenes(tally, args.springfit, tmp, args.source_dir)


def main(argv=None):
    return run(argv, "springfit FEM reference against CalculiX", checks,
               tools=("ccx (CalculiX)", "gmsh"), needs_springfit=True)


if __name__ == "__main__":
    sys.exit(main())
