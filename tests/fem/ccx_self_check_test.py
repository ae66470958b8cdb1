#!/usr/bin/env python3
"""The ccx harness (tests/fem/ccx_reference.py) proved right on problems with closed-form
answers, and on one against an independent 2D solver.

Usage: ccx_self_check_test.py [SPRINGFIT_BINARY PROJECT_SOURCE_DIR] [--keep DIR]

`self_check()` runs the harness on: a uniaxial bar (u = F L / (E A), lateral contraction nu) in
plane stress, plane strain and 3D; homogeneous deformations of distorted meshes driven by the
consistent nodal loads of a uniform stress (patch tests), linear and St. Venant-Kirchhoff
(NLGEOM, about 8% strain), with one and with two material regions, driven by forces and by
prescribed displacements; and, not a closed form, a sheared 5x5 plate against a small direct
2D solver written here (direct_2d), where ccx's own plane-stress element CPS3 would be 1e-2
off. Together they show that the plane-strain element with the plane-stress ORTHO constants
reproduces the 2D plane-stress law exactly (to the 7 digits ccx prints), linear and
St. Venant-Kirchhoff. (The harness's tractions, which need no ccx: ccx_traction_check_test.py;
springfit against the harness: ccx_scenes_test.py.)

Prints one line per comparison and ends with `N passed, M failed`; exits 1 if any failed
(or ccx is missing), 2 on bad usage. Python 3 standard library only (the shared part:
ccx_validation_support.py).
"""

import math
import os
import sys

from ccx_validation_support import (block_nodes, block_tets, grid_nodes, grid_triangles,
                                    rel_diff, run)

TOL_SELF = 1e-6          # closed forms; the ccx .dat carries 7 significant digits

cr = None  # the ccx_reference module, imported by run()


# ----------------------------------------------------------------------------------------
# Boundary faces


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

    # 4. The harness's tractions need no ccx: ccx_traction_check_test.py checks them.

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




def checks(tally, args, tmp, harness):
    global cr
    cr = harness
    self_check(tally, os.path.join(tmp, "self-check") if args.keep else None)


def main(argv=None):
    return run(argv, "the ccx harness against closed forms and a direct 2D solver", checks,
               tools=("ccx (CalculiX)",))


if __name__ == "__main__":
    sys.exit(main())
