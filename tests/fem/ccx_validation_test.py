#!/usr/bin/env python3
"""Validates springfit's FEM reference models against CalculiX (ccx).

Usage: ccx_validation_test.py SPRINGFIT_BINARY PROJECT_SOURCE_DIR
       ccx_validation_test.py [SPRINGFIT_BINARY PROJECT_SOURCE_DIR] --self-check-only

First `self_check()` proves the ccx harness (tests/fem/ccx_reference.py) right on problems
with closed-form answers: a uniaxial bar (u = F L / (E A), lateral contraction nu) in plane
stress, plane strain and 3D; homogeneous deformations of distorted meshes driven by the
consistent nodal loads of a uniform stress (patch tests), linear and St. Venant-Kirchhoff
(NLGEOM, about 8% strain), with one and with two material regions, driven by forces and by
prescribed displacements; and, not a closed form, a sheared 5x5 plate against a small direct
2D solver written here (direct_2d), where ccx's own plane-stress element CPS3 would be 1e-2
off. Together they show that the plane-strain element with the plane-stress ORTHO constants
reproduces the 2D plane-stress law exactly (to the 7 digits ccx prints), linear and
St. Venant-Kirchhoff. It also checks, without ccx, the harness's own resolution of tractions
into nodal forces against hand values and exact resultants and moments
(traction_self_check), and that the harness refuses load-case fields it does not model.

Then it generates scenes (a 4-triangle patch, a 5x5 plate, a gmsh-meshed plate with an
elliptical hole, a tetrahedral block, their St. Venant-Kirchhoff versions, prescribed
displacements, two material regions, a distorted tetrahedral block under a per_area and a
total traction) and reads the committed examples loaded by tractions (examples/
fem-plate-5x5.json, linear plane stress; examples/fem-kidney-2d-nl.json, St. Venant-Kirchhoff
plane strain), writes them to a temporary directory, runs
`SPRINGFIT_BINARY reference SCENE --json` and the ccx harness on each, and compares the
positions: max over nodes of |x_springfit - x_ccx| / max over nodes of |u_ccx| per load case.
Tolerances: linear 1e-6 (ccx prints 7 significant digits, so its answer carries up to 5e-7 of
that), St. Venant-Kirchhoff 1e-4. On scenes with tractions it also compares the nodal forces
springfit prints in its resolved `load_cases` with the harness's (max |df| / max |f| over the
scene's traction cases, tolerance 1e-12).

Prints one line per comparison and ends with `N passed, M failed`; exits 1 if any failed
(or ccx / gmsh are missing), 2 on bad usage. Python 3 standard library only.
"""

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))

TOL_LINEAR = 1e-6
TOL_SVK = 1e-4
TOL_SELF = 1e-6          # closed forms; the ccx .dat carries 7 significant digits
TOL_FORCES = 1e-12       # nodal forces of tractions: the same sums, to round-off
SPRINGFIT_TIMEOUT = 120.0
MISSING_TOOL = "{tool} not found: run scripts/install-deps.sh"

cr = None  # the ccx_reference module, imported in main()


def _import_harness(source_dir):
    global cr
    for d in ([os.path.join(source_dir, "tests", "fem")] if source_dir else []) + [HERE]:
        if os.path.isfile(os.path.join(d, "ccx_reference.py")):
            sys.path.insert(0, d)
            break
    import ccx_reference
    cr = ccx_reference


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


def patch_mesh():
    """A unit square split into 4 triangles around a centre node (one written clockwise)."""
    nodes = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]]
    tris = [[0, 1, 4], [1, 2, 4], [2, 3, 4], [0, 3, 4]]  # the last one is clockwise
    return nodes, tris


def boundary_faces(nodes, elements):
    """Boundary edges (2D) or triangles (3D), each with its element: (face, element index),
    face oriented so that its normal points out of the element."""
    dim = len(nodes[0])
    count = {}
    for k, e in enumerate(elements):
        subs = [[e[a] for a in range(len(e)) if a != skip] for skip in range(len(e))]
        for s, skip in zip(subs, range(len(e))):
            key = tuple(sorted(s))
            count.setdefault(key, []).append((k, s, e[skip]))
    faces = []
    for key, owners in count.items():
        if len(owners) != 1:
            continue
        k, s, opposite = owners[0]
        n = face_normal([nodes[i] for i in s])
        to_opp = [nodes[opposite][d] - nodes[s[0]][d] for d in range(dim)]
        if sum(a * b for a, b in zip(n, to_opp)) > 0:
            s = [s[1], s[0]] + s[2:]
        faces.append((s, k))
    return faces


def face_normal(pts):
    """Area-weighted normal (length for edges in 2D, area for triangles in 3D), any sign."""
    if len(pts) == 2:
        dx, dy = pts[1][0] - pts[0][0], pts[1][1] - pts[0][1]
        return [dy, -dx]
    u = [pts[1][d] - pts[0][d] for d in range(3)]
    v = [pts[2][d] - pts[0][d] for d in range(3)]
    return [0.5 * (u[1] * v[2] - u[2] * v[1]), 0.5 * (u[2] * v[0] - u[0] * v[2]),
            0.5 * (u[0] * v[1] - u[1] * v[0])]


# ----------------------------------------------------------------------------------------
# Closed forms


def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(len(b))) for j in range(len(b[0]))]
            for i in range(len(a))]


def transpose(a):
    return [list(r) for r in zip(*a)]


def law_stress(strain, material, dim, plane):
    """sigma (linear) or S (St. Venant-Kirchhoff) for a strain tensor: the 3D law, or the 2D
    plane-strain law (lambda) or the 2D plane-stress law (lambda* = 2 lambda mu/(lambda+2mu))."""
    lam, mu = material.lame()
    if dim == 2 and plane == "stress":
        lam = 2.0 * lam * mu / (lam + 2.0 * mu)
    tr = sum(strain[i][i] for i in range(dim))
    return [[(lam * tr if i == j else 0.0) + 2.0 * mu * strain[i][j] for j in range(dim)]
            for i in range(dim)]


def nominal_stress(H, material, dim, plane):
    """The stress whose traction P N on the reference boundary equilibrates x = X + H X:
    linear: sigma(sym H); St. Venant-Kirchhoff: P = F S(E), F = I + H, E = (F^T F - I)/2."""
    eye = [[1.0 if i == j else 0.0 for j in range(dim)] for i in range(dim)]
    if material.model == "linear":
        eps = [[0.5 * (H[i][j] + H[j][i]) for j in range(dim)] for i in range(dim)]
        return law_stress(eps, material, dim, plane)
    F = [[eye[i][j] + H[i][j] for j in range(dim)] for i in range(dim)]
    C = matmul(transpose(F), F)
    E = [[0.5 * (C[i][j] - eye[i][j]) for j in range(dim)] for i in range(dim)]
    return matmul(F, law_stress(E, material, dim, plane))


def homogeneous_case(nodes, elements, materials, element_materials, H, supports, dim,
                     plane="stress", thickness=1.0, name="", all_boundary_held=False):
    """A load case whose exact answer is x = X + H X (H the displacement gradient about the
    first node): the consistent nodal loads of the uniform nominal stress of each element on
    the boundary, and the supports {node: [dofs]} held at their exact displacement. With
    all_boundary_held, every boundary node is held instead and there is no load.
    Returns (LoadCase, exact positions)."""
    o = nodes[0]
    def exact_u(p):
        return [sum(H[i][j] * (p[j] - o[j]) for j in range(dim)) for i in range(dim)]
    expected = [[p[d] + u[d] for d in range(dim)] for p in nodes for u in [exact_u(p)]]
    case = cr.LoadCase(name)
    faces = boundary_faces(nodes, elements)
    if all_boundary_held:
        for s, _ in faces:
            for i in s:
                u = exact_u(nodes[i])
                case.constraints[i] = {d: u[d] for d in range(dim)}
        return case, expected
    stresses = [nominal_stress(H, m, dim, plane) for m in materials]
    for s, k in faces:
        P = stresses[element_materials[k]]
        n = face_normal([nodes[i] for i in s])  # outward, |n| = length or area
        t = [sum(P[i][j] * n[j] for j in range(dim)) for i in range(dim)]
        share = (thickness / 2.0) if dim == 2 else (1.0 / 3.0)
        for i in s:
            acc = case.forces.setdefault(i, [0.0] * dim)
            for d in range(dim):
                acc[d] += t[d] * share
    for i, dofs in supports.items():
        u = exact_u(nodes[i])
        case.constraints[i] = {d: u[d] for d in dofs}
    return case, expected


def check_against(tally, label, problem, expected_per_case, tol=TOL_SELF, workdir=None):
    if workdir:
        workdir = os.path.join(workdir, "".join(c if c.isalnum() or c in "-_." else "_"
                                                for c in problem.name))
    try:
        got, info = cr.solve(problem, workdir)
    except (cr.CcxError, cr.SceneError) as e:
        for k, case in enumerate(problem.cases):
            tally.fail(f"{label} {case.name}", str(e))
        return
    for k, case in enumerate(problem.cases):
        d = rel_diff(got[k], expected_per_case[k], problem.nodes)
        note = ""
        if info[k]["iterations"] > 1:
            note = (f"  [ccx: {info[k]['increments']} increment(s), "
                    f"{info[k]['iterations']} iterations, {info[k]['cutbacks']} cutbacks]")
        tally.line(f"{label} {case.name}", d, tol, note)


def self_check(tally, workdir=None):
    """The ccx harness against closed forms and direct_2d (see the module docstring)."""
    print("== self-check: the ccx harness against closed forms and a direct 2D solver", flush=True)
    M = cr.Material

    # 1. Uniaxial bar 2 x 1 (thickness 0.1 in 2D; 2 x 1 x 1 in 3D), loaded by a total force F
    #    on its right end, left end on rollers: u_x(L) = F L / (E' A), u_y = -nu' eps y.
    for plane, nu in (("stress", 0.3), ("strain", 0.45), ("3d", 0.3)):
        E, F, L, W, t = 10.0, 0.02, 2.0, 1.0, 0.1
        mat = M("linear", E, nu)
        if plane == "3d":
            nodes = block_nodes(4, 2, 2, h=0.5)
            elems = block_tets(4, 2, 2)
            area, e_eff, nu_eff, dim = W * W, E, nu, 3
        else:
            nodes = grid_nodes(4, 2, 0.5, 0.5)
            elems = grid_triangles(4, 2)
            area, dim = W * t, 2
            e_eff, nu_eff = (E, nu) if plane == "stress" else (E / (1 - nu * nu), nu / (1 - nu))
        eps = F / (e_eff * area)
        case = cr.LoadCase("uniaxial")
        right = [i for i, p in enumerate(nodes) if abs(p[0] - L) < 1e-12]
        faces = [s for s, _ in boundary_faces(nodes, elems)
                 if all(abs(nodes[i][0] - L) < 1e-12 for i in s)]
        for s in faces:  # consistent nodal loads of a uniform traction F / A
            a = math.sqrt(sum(c * c for c in face_normal([nodes[i] for i in s])))
            for i in s:
                share = a * (t if dim == 2 else 1.0) / len(s)
                case.forces.setdefault(i, [0.0] * dim)[0] += F / area * share
        assert len(right) > 0 and abs(sum(f[0] for f in case.forces.values()) - F) < 1e-15
        for i, p in enumerate(nodes):
            if p[0] == 0.0:
                case.constraints[i] = {0: 0.0}
        case.constraints[0] = {d: 0.0 for d in range(dim)}
        if dim == 3:  # a node on the y axis held in z stops the rotation about x
            yaxis = [i for i, p in enumerate(nodes) if p[0] == 0 and p[2] == 0 and p[1] > 0][0]
            case.constraints[yaxis] = {0: 0.0, 2: 0.0}
        expected = [[p[0] + eps * p[0]] + [p[d] - nu_eff * eps * p[d] for d in range(1, dim)]
                    for p in nodes]
        prob = cr.Problem(nodes, elems, [mat], [0] * len(elems), [case],
                          plane if dim == 2 else "stress", t if dim == 2 else 1.0,
                          name=f"bar-{plane}")
        check_against(tally, f"self-check bar {plane} nu={nu} (u=FL/(E'A)={eps * L:.6g})",
                      prob, [expected], workdir=workdir)

    # 2. Patch tests: homogeneous deformations of distorted meshes, loads from the uniform
    #    stress (linear: ~1% strain; St. Venant-Kirchhoff: ~8% strain, NLGEOM).
    def wobble2(i, j):
        return (0.13 * math.sin(3.1 * i + 1.7 * j), 0.11 * math.cos(2.3 * i - 1.3 * j))

    def wobble3(i, j, k):
        return (0.12, -0.09, 0.07)

    nodes2 = grid_nodes(3, 3, perturb=wobble2)
    tris = grid_triangles(3, 3)
    nodes3 = block_nodes(2, 2, 2, perturb=wobble3)
    tets = block_tets(2, 2, 2)
    sup2 = {0: [0, 1], 3: [1]}              # (0,0) fixed, (3,0) on a roller
    sup3 = {0: [0, 1, 2], 2: [1, 2], 6: [2]}  # (0,0,0); (2,0,0); (0,2,0)
    h_lin2 = [[0.010, 0.004], [-0.002, -0.006]]
    h_svk2 = [[0.080, 0.050], [0.000, -0.030]]
    h_lin3 = [[0.010, 0.003, -0.002], [0.001, -0.004, 0.002], [0.000, 0.003, 0.006]]
    h_svk3 = [[0.080, 0.040, 0.000], [0.000, -0.030, 0.030], [0.000, 0.000, 0.060]]
    runs = [
        ("plane stress", 2, "stress", 0.3, nodes2, tris, sup2, h_lin2, h_svk2),
        ("plane strain", 2, "strain", 0.45, nodes2, tris, sup2, h_lin2, h_svk2),
        ("3d", 3, "stress", 0.3, nodes3, tets, sup3, h_lin3, h_svk3),
    ]
    for label, dim, plane, nu, nodes, elems, sup, h_lin, h_svk in runs:
        for model, H in (("linear", h_lin), ("st_venant_kirchhoff", h_svk)):
            mat = M(model, 10.0, nu)
            th = 0.1 if dim == 2 else 1.0
            cases, exp = [], []
            c, x = homogeneous_case(nodes, elems, [mat], [0] * len(elems), H, sup, dim,
                                    plane, th, "forces")
            cases.append(c), exp.append(x)
            c, x = homogeneous_case(nodes, elems, [mat], [0] * len(elems), H, sup, dim,
                                    plane, th, "displacements", all_boundary_held=True)
            cases.append(c), exp.append(x)
            prob = cr.Problem(nodes, elems, [mat], [0] * len(elems), cases, plane, th,
                              name=f"patch-{label}-{model}")
            check_against(tally, f"self-check patch {label} nu={nu} {model}", prob, exp,
                          workdir=workdir)

    # 3. Two regions in parallel (bottom half E = 10, top half E = 30, same nu): a uniaxial
    #    stretch along x is homogeneous (tractions match across the horizontal interface).
    nodes = grid_nodes(4, 2, 0.5, 0.5)
    elems = grid_triangles(4, 2)
    ids = [0 if sum(nodes[i][1] for i in e) / 3 < 0.5 else 1 for e in elems]
    for model, e11 in (("linear", 0.01), ("st_venant_kirchhoff", 0.08)):
        mats = [M(model, 10.0, 0.3), M(model, 30.0, 0.3)]
        # lateral stretch for S22 = 0 with the plane-stress law: E22 = -nu E11
        if model == "linear":
            H = [[e11, 0.0], [0.0, -0.3 * e11]]
        else:
            big_e11 = 0.5 * ((1 + e11) ** 2 - 1)
            H = [[e11, 0.0], [0.0, math.sqrt(1 - 2 * 0.3 * big_e11) - 1]]
        c, x = homogeneous_case(nodes, elems, mats, ids, H, {0: [0, 1], 4: [1]}, 2,
                                "stress", 0.1, "uniaxial")
        prob = cr.Problem(nodes, elems, mats, ids, [c], "stress", 0.1,
                          name=f"regions-{model}")
        check_against(tally, f"self-check two regions plane stress {model}", prob, [x],
                      workdir=workdir)

    # 4. The harness's tractions (no ccx): nodal forces against hand values, resultants and
    #    moments; refusal of load-case fields it does not model.
    traction_self_check(tally)

    # 5. Not a closed form but an independent solver: a non-homogeneous state (the 5x5 plate,
    #    bottom fixed, top row sheared), where ccx's own plane-stress element (CPS3, expanded
    #    into wedges with a free thickness) is off by 1e-2 at nu = 0.45 while the plane-strain
    #    element with the plane-stress ORTHO constants must agree with the 2D law exactly.
    nodes = grid_nodes(4, 4)
    tris = grid_triangles(4, 4)
    fixed = {0, 1, 2, 3, 4}
    for model, plane, nu, fx in (("linear", "stress", 0.45, 0.01),
                                 ("st_venant_kirchhoff", "stress", 0.3, 0.01),
                                 ("st_venant_kirchhoff", "strain", 0.3, 0.01)):
        material = M(model, 10.0, nu)
        forces = {i: [fx, 0.0] for i in range(20, 25)}
        exact = direct_2d(nodes, tris, material, plane, 0.1, fixed, forces)
        case = cr.LoadCase("shear", {i: {0: 0.0, 1: 0.0} for i in fixed}, forces)
        prob = cr.Problem(nodes, tris, [material], [0] * len(tris), [case], plane, 0.1,
                          name=f"plate-{plane}-{model}")
        check_against(tally, f"self-check plate plane {plane} nu={nu} {model} vs direct 2D "
                      f"solver", prob, [exact], workdir=workdir)


def traction_self_check(tally):
    """ccx_reference's resolution of tractions into nodal forces (problem_from_scene) against
    values worked out by hand: a traction t on linear facets is equivalent to nodal forces
    whose sum is the resultant t x (loaded length or area) and whose first moment
    sum_i f_i x_i is t x the integral of x over the loaded facets (exact for linear shape
    functions); on a 2 x 1 bar's right end (3 nodes, edges of length 0.5) the shares are
    1/4, 1/2, 1/4 of the total. Also: the share of a constrained node is dropped, interior
    edges and faces carry nothing, `per_length` is not multiplied by the thickness, and
    unknown fields are refused."""
    def run(label, sc, expect):
        """expect(cases) -> (ok, detail)."""
        try:
            prob = cr.problem_from_scene(sc)
        except cr.SceneError as e:
            tally.fail(label, f"harness refused the scene: {e}")
            return
        ok, detail = expect(prob.cases)
        tally.check(label, ok, detail)

    def close(a, b):
        return abs(a - b) <= 1e-14 * max(1.0, abs(b))

    def resultant(forces, d):
        return math.fsum(f[d] for f in forces.values())

    mat = {"model": "linear", "young": 10.0, "poisson": 0.3}

    # 2D: 2 x 1 bar, 5 x 3 nodes at spacing 0.5, thickness 0.1 (which must not scale tractions).
    nodes = grid_nodes(4, 2, 0.5, 0.5)
    tris = grid_triangles(4, 2)
    right = [i for i, p in enumerate(nodes) if p[0] == 2.0]    # y = 0, 0.5, 1
    left = [i for i, p in enumerate(nodes) if p[0] == 0.0]
    sets = {"left": left, "right": right, "all": list(range(len(nodes))),
            "corner": [right[0], right[1]]}
    base = {"name": "bar", "nodes": nodes, "node_sets": sets,
            "reference": {"type": "fem", "elements": tris, "material": mat, "thickness": 0.1}}
    F, q = 0.02, 0.03
    sc = dict(base, load_cases=[
        {"name": "total", "fixed": "left", "tractions": [{"on": "right", "total": [F, 0.0]}]},
        {"name": "per_length", "fixed": "left",
         "tractions": [{"on": "right", "per_length": [0.0, q]}]},
        {"name": "held corner", "fixed": left + [right[0]],
         "tractions": [{"on": "right", "total": [F, 0.0]}]},
        {"name": "with a force", "fixed": "left",
         "forces": [{"node": right[1], "force": [0.0, 0.001]}],
         "tractions": [{"on": "right", "total": [F, 0.0]}, {"on": "corner", "total": [0.0, F]}]},
        {"name": "whole boundary", "fixed": "left",
         "tractions": [{"on": "all", "per_length": [q, 0.0]}]},
    ])
    a, b, c = right

    def expect_2d(cases):
        want = [
            {a: [F / 4, 0.0], b: [F / 2, 0.0], c: [F / 4, 0.0]},
            {a: [0.0, q / 4], b: [0.0, q / 2], c: [0.0, q / 4]},
            {b: [F / 2, 0.0], c: [F / 4, 0.0]},
            {a: [F / 4, F / 2], b: [F / 2, F / 2 + 0.001], c: [F / 4, 0.0]},
        ]
        bad = []
        for k, w in enumerate(want):
            got = cases[k].forces
            if set(got) != set(w) or not all(close(got[i][d], w[i][d])
                                             for i in w for d in range(2)):
                bad.append(f"{cases[k].name}: {got} != {w}")
        # The perimeter is 6; the fixed left end takes all of its 1 and half of each of the
        # two edges (length 0.5) that end on it: q (6 - 1 - 2 x 0.25) on the free nodes.
        got = cases[4].forces
        want_sum = q * (6.0 - 1.0 - 2 * 0.25)
        if not close(resultant(got, 0), want_sum) or resultant(got, 1) != 0.0:
            bad.append(f"whole boundary: resultant {resultant(got, 0)} != {want_sum}")
        return not bad, "; ".join(bad) or "5 cases"

    run("self-check tractions 2D nodal forces (bar end, held node, forces add, boundary only)",
        sc, expect_2d)

    # 3D: 2 x 1 x 1 block, 5 x 3 x 3 nodes at spacing 0.5; its right end is the unit square
    # x = 2 (16 triangles). Resultant t; first moments sum f_z y = sum f_z z = t_z / 2.
    nodes = block_nodes(4, 2, 2, h=0.5)
    tets = block_tets(4, 2, 2)
    right = [i for i, p in enumerate(nodes) if p[0] == 2.0]
    left = [i for i, p in enumerate(nodes) if p[0] == 0.0]
    sets = {"left": left, "right": right, "all": list(range(len(nodes)))}
    base = {"name": "block", "nodes": nodes, "node_sets": sets,
            "reference": {"type": "fem", "elements": tets, "material": mat}}
    p, T = 0.03, 0.05
    sc = dict(base, load_cases=[
        {"name": "per_area", "fixed": "left",
         "tractions": [{"on": "right", "per_area": [0.0, 0.0, p]}]},
        {"name": "total", "fixed": "left",
         "tractions": [{"on": "right", "total": [0.0, 0.0, T]}]},
        {"name": "whole boundary", "fixed": "left",
         "tractions": [{"on": "all", "per_area": [p, 0.0, 0.0]}]},
    ])

    def expect_3d(cases):
        bad = []
        for k, tz in ((0, p), (1, T)):
            f = cases[k].forces
            r = [resultant(f, d) for d in range(3)]
            my = math.fsum(v[2] * nodes[i][1] for i, v in f.items())
            mz = math.fsum(v[2] * nodes[i][2] for i, v in f.items())
            if not (close(r[2], tz) and r[0] == 0.0 and r[1] == 0.0 and close(my, tz / 2)
                    and close(mz, tz / 2) and set(f) == set(right)):
                bad.append(f"{cases[k].name}: resultant {r}, moments {my}, {mz} (want {tz}, "
                           f"{tz / 2})")
        # The surface is 10; the fixed left face's nodes take all of its 1 and, on the strip
        # 0 <= x <= 0.5 of the four sides (perimeter 4), the integral of the sum of their hat
        # functions, 1 - 2x: 4 x 0.25 = 1. The free nodes carry p (10 - 1 - 1) = 8 p.
        f = cases[2].forces
        free_sum = resultant(f, 0)
        if not close(free_sum, 8.0 * p) or any(i in f for i in left):
            bad.append(f"whole boundary: free resultant {free_sum} != {8 * p}")
        return not bad, "; ".join(bad) or "3 cases"

    run("self-check tractions 3D nodal forces (resultants, moments, boundary only)", sc,
        expect_3d)

    # Refusals: what the harness does not model must not pass silently.
    plain = {"name": "refusals", "nodes": grid_nodes(1, 1), "node_sets": {"top": [2, 3]},
             "reference": {"type": "fem", "elements": grid_triangles(1, 1), "material": mat}}
    good = {"name": "ok", "fixed": [0, 1], "tractions": [{"on": "top", "total": [0.0, 0.1]}]}
    refusals = [
        ("an unknown load-case field", dict(good, pressure=[{"on": "top", "value": 1.0}])),
        ("a 3D density in 2D", dict(good, tractions=[{"on": "top", "per_area": [0.0, 1.0]}])),
        ("an unknown traction field", dict(good, tractions=[{"on": "top", "total": [0.0, 1.0],
                                                              "follower": True}])),
        ("total and per_length", dict(good, tractions=[{"on": "top", "total": [0.0, 1.0],
                                                         "per_length": [0.0, 1.0]}])),
        ("a node list as on", dict(good, tractions=[{"on": [2, 3], "total": [0.0, 1.0]}])),
        ("a set with no boundary edge", dict(good, fixed=[1, 2])),
        ("an unknown force field", dict(good, forces=[{"node": 2, "force": [0.0, 1.0],
                                                       "follower": True}])),
    ]
    # (top = [2, 3] is a boundary edge; for "a set with no boundary edge" the set becomes
    # the ends of the diagonal (0, 3), the one interior edge.)
    missed = []
    for why, case in refusals:
        sc = dict(plain, load_cases=[case])
        if why == "a set with no boundary edge":
            sc["node_sets"] = {"top": [0, 3]}
        try:
            cr.problem_from_scene(sc)
            missed.append(why)
        except cr.SceneError:
            pass
    try:
        cr.problem_from_scene(dict(plain, load_cases=[good]))
    except cr.SceneError as e:
        missed.append(f"the valid case was refused: {e}")
    tally.check("self-check the harness refuses what it does not model", not missed,
                "accepted: " + ", ".join(missed) if missed else f"{len(refusals)} refusals")


def direct_2d(nodes, tris, material, plane, thickness, fixed, forces):
    """An independent 2D solver for the self-check: linear triangles, the 2D law of
    law_stress (small strain, or St. Venant-Kirchhoff with P = F S), dead nodal loads, Newton
    with a central-difference tangent and a dense elimination. Returns the positions."""
    dofs = [d for d in range(2 * len(nodes)) if d // 2 not in fixed]
    grads = []
    for e in tris:
        (x0, y0), (x1, y1), (x2, y2) = [nodes[i] for i in e]
        a2 = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        grads.append(([(y1 - y2) / a2, (x2 - x1) / a2], [(y2 - y0) / a2, (x0 - x2) / a2],
                      [(y0 - y1) / a2, (x1 - x0) / a2], 0.5 * abs(a2) * thickness))

    def internal(x):
        f = [0.0] * (2 * len(nodes))
        for e, (g0, g1, g2, vol) in zip(tris, grads):
            g = (g0, g1, g2)
            H = [[sum((x[e[a]][i] - nodes[e[a]][i]) * g[a][j] for a in range(3))
                  for j in range(2)] for i in range(2)]
            P = nominal_stress(H, material, 2, plane)
            for a in range(3):
                for i in range(2):
                    f[2 * e[a] + i] += vol * (P[i][0] * g[a][0] + P[i][1] * g[a][1])
        return f

    fext = [0.0] * (2 * len(nodes))
    for i, v in forces.items():
        fext[2 * i] += v[0]
        fext[2 * i + 1] += v[1]
    x = [list(p) for p in nodes]
    size = max(math.dist(p, nodes[0]) for p in nodes)
    scale = max(abs(v) for v in fext)
    for _ in range(30):
        f = internal(x)
        r = [fext[d] - f[d] for d in dofs]
        if max(abs(v) for v in r) <= 1e-11 * scale:  # the round-off floor is ~1e-13
            return x
        h = 1e-6 * size
        cols = []
        for d in dofs:
            x[d // 2][d % 2] += h
            fp = internal(x)
            x[d // 2][d % 2] -= 2 * h
            fm = internal(x)
            x[d // 2][d % 2] += h
            cols.append([(fp[q] - fm[q]) / (2 * h) for q in dofs])
        m = len(dofs)
        A = [[cols[j][i] for j in range(m)] + [r[i]] for i in range(m)]
        for c in range(m):
            p = max(range(c, m), key=lambda k: abs(A[k][c]))
            A[c], A[p] = A[p], A[c]
            for k in range(c + 1, m):
                q = A[k][c] / A[c][c]
                for j in range(c, m + 1):
                    A[k][j] -= q * A[c][j]
        dx = [0.0] * m
        for k in range(m - 1, -1, -1):
            dx[k] = (A[k][m] - sum(A[k][j] * dx[j] for j in range(k + 1, m))) / A[k][k]
        for k, d in enumerate(dofs):
            x[d // 2][d % 2] += dx[k]
    raise RuntimeError("direct_2d: Newton did not converge")


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


# ----------------------------------------------------------------------------------------


def main(argv=None):
    ap = argparse.ArgumentParser(description="springfit FEM reference against CalculiX")
    ap.add_argument("springfit", nargs="?", help="the springfit binary")
    ap.add_argument("source_dir", nargs="?", help="the project's source directory")
    ap.add_argument("--self-check-only", action="store_true",
                    help="only check the ccx harness against closed forms")
    ap.add_argument("--keep", metavar="DIR", help="write scenes and ccx decks here and keep them")
    args = ap.parse_args(argv)
    if not args.self_check_only and (not args.springfit or not args.source_dir):
        ap.print_usage(sys.stderr)
        print("ccx_validation_test.py: SPRINGFIT_BINARY and PROJECT_SOURCE_DIR are required "
              "(or --self-check-only)", file=sys.stderr)
        return 2
    _import_harness(args.source_dir)
    missing = [t for t, exe in (("ccx (CalculiX)", os.environ.get("CCX", "ccx")),
                                ("gmsh", "gmsh"))
               if not shutil.which(exe) and not (t == "gmsh" and args.self_check_only)]
    if missing:
        for t in missing:
            print(MISSING_TOOL.format(tool=t), file=sys.stderr)
        return 1
    if args.springfit and not args.self_check_only and not os.path.isfile(args.springfit):
        print(f"ccx_validation_test.py: no springfit binary at {args.springfit}", file=sys.stderr)
        return 2

    start = time.monotonic()
    tally = Tally()
    tmp = args.keep or tempfile.mkdtemp(prefix="ccx_validation_")
    os.makedirs(tmp, exist_ok=True)
    try:
        self_check(tally, os.path.join(tmp, "self-check") if args.keep else None)
        if not args.self_check_only:
            compare_scenes(tally, args.springfit, tmp, args.source_dir)
    finally:
        if not args.keep:
            shutil.rmtree(tmp, ignore_errors=True)
    print(f"({time.monotonic() - start:.1f} s)")
    print(f"{tally.passed} passed, {tally.failed} failed")
    return 1 if tally.failed else 0


if __name__ == "__main__":
    sys.exit(main())
