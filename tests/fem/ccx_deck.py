"""Deck writing for the ccx harness (ccx_reference.py): one CalculiX input deck per load case
(write_deck): elements oriented for ccx, moduli and forces scaled above ccx's absolute residual
floor (unit_scale), the *ELASTIC card of each material (elastic_card) and tight convergence
controls for NLGEOM steps. Python 3 standard library only.
"""

import math

from ccx_problem import SceneError

# Convergence controls for geometrically nonlinear steps (*CONTROLS; defaults in brackets).
# FIELD: R_n, largest residual / time-average force [5e-3]; C_n, largest correction / largest
# displacement increment [1e-2]; q0, qu (left default); R_p, R_n after I_P iterations [2e-2];
# eps, zero-force threshold [1e-5]; C_eps [1e-3]; R_l, residual for convergence in a single
# iteration [1e-8]. ccx accepts an iteration when the residual is below R_n and either the
# correction is below C_n or the correction extrapolated from the residual decrease is, so
# with Newton's quadratic convergence the answer is good to far better than 1e-9 (also see
# unit_scale: the residual has an absolute floor of 1e-6).
NLGEOM_FIELD_CONTROLS = "1.e-10,1.e-9,,,1.e-10,1.e-5,1.e-9,1.e-12"
# TIME INCREMENTATION: I_0 [4], I_R [8], I_P [9], I_C max iterations [16], I_L [10], I_G [4],
# I_S, I_A max cutbacks [5]: more room, as the tight criteria take a few more iterations. The
# step starts with one increment (1.0) and ccx cuts back when it diverges.
NLGEOM_TIME_CONTROLS = "12,16,40,40,14,6,,10"


def fnum(x, width=20):
    """A float as text of at most `width` characters (ccx reads at most 20 per field)."""
    x = float(x)
    if x == 0.0:
        return "0.0"
    s = repr(x)
    if len(s) <= width and ("." in s or "e" in s):
        return s
    for p in range(16, 0, -1):
        s = "%.*e" % (p, x)
        if len(s) <= width:
            return s
    raise ValueError(f"cannot format {x}")


def _signed_measure(pts):
    if len(pts) == 3:
        (x0, y0), (x1, y1), (x2, y2) = [p[:2] for p in pts]
        return 0.5 * ((x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0))
    a, b, c, d = pts
    u = [b[i] - a[i] for i in range(3)]
    v = [c[i] - a[i] for i in range(3)]
    w = [d[i] - a[i] for i in range(3)]
    return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
            + u[2] * (v[0] * w[1] - v[1] * w[0])) / 6.0


def oriented(problem):
    """Elements with positive area/volume (ccx needs counter-clockwise / positive tets)."""
    out = []
    for k, e in enumerate(problem.elements):
        m = _signed_measure([problem.nodes[i] for i in e])
        scale = max(_edge2(problem.nodes, e)) ** (0.5 * (len(e) - 1))  # longest edge^dim
        if abs(m) <= 1e-12 * scale:
            raise SceneError(f"reference.elements[{k}]: degenerate element (zero "
                             f"{'area' if len(e) == 3 else 'volume'})")
        out.append(list(e) if m > 0 else [e[0], e[2], e[1]] + list(e[3:]))
    return out


def _edge2(nodes, e):
    return [sum((nodes[a][d] - nodes[b][d]) ** 2 for d in range(len(nodes[a])))
            for a in e for b in e if a < b]


def unit_scale(problem):
    """The factor applied to moduli and forces in the decks (displacements do not change).

    ccx treats a residual force below 1e-6 in absolute value as zero and then declares
    convergence at once (checkconvergence: `if(ram[0]<1.e-6) ram[0]=0.;` with the R_l
    criterion), so in the small units of springfit's scenes (E ~ 10, forces ~ 0.01) NLGEOM
    steps would stop after two or three Newton iterations, 1e-5 off. Scaling the units so
    that E x length^(d-1) x thickness is ~1e10 (nodal forces ~1e7 at 1% strain) puts that
    floor below 1e-12 of the forces. A power of ten keeps the deck readable; the arithmetic
    is relative, so the scale changes nothing else."""
    lo = [min(p[d] for p in problem.nodes) for d in range(problem.dim)]
    hi = [max(p[d] for p in problem.nodes) for d in range(problem.dim)]
    length = math.sqrt(sum((b - a) ** 2 for a, b in zip(lo, hi)))
    area = length ** (problem.dim - 1) * (problem.thickness if problem.dim == 2 else 1.0)
    young = max(m.young for m in problem.materials)
    return 10.0 ** round(math.log10(1e10 / (young * area)))


def elastic_card(material, dim, plane, scale=1.0):
    """The *ELASTIC card lines for one material, moduli multiplied by scale."""
    e, nu = material.young * scale, material.poisson
    if dim == 2 and plane == "stress":
        c11 = e / (1.0 - nu * nu)
        c12 = nu * e / (1.0 - nu * nu)
        g = e / (2.0 * (1.0 + nu))
        # D1111, D1122, D2222, D1133, D2233, D3333, D1212, D1313 / D2323. The zz row is
        # decoupled (D1133 = D2233 = 0) and E33 = 0 in plane strain, so it never contributes;
        # D3333 = E keeps the 3D matrix positive definite.
        first = [c11, c12, c11, 0.0, 0.0, e, g, g]
        return ["*ELASTIC, TYPE=ORTHO",
                ", ".join(fnum(v) for v in first),
                fnum(g)]
    return ["*ELASTIC", f"{fnum(e)}, {fnum(nu)}"]


def write_deck(problem, case_index, used=None):
    """The text of the CalculiX input deck for one load case."""
    dim = problem.dim
    case = problem.cases[case_index]
    if used is None:
        used = sorted({i for e in problem.elements for i in e})
    elems = oriented(problem)
    nonlinear = problem.nonlinear()
    etype = "C3D4" if dim == 3 else "CPE3"
    scale = unit_scale(problem)
    lines = [f"** springfit ccx_reference: scene '{problem.name}', load case {case_index} "
             f"'{case.name}'",
             "** node i of the scene is node i+1 here",
             f"** moduli and forces are the scene's times {scale:g} (see unit_scale)",
             "*NODE, NSET=NALL"]
    for i in used:
        lines.append(f"{i + 1}, " + ", ".join(fnum(c) for c in problem.nodes[i]))
    for m in range(len(problem.materials)):
        ids = [k for k in range(len(elems)) if problem.element_materials[k] == m]
        if not ids:
            continue
        lines.append(f"*ELEMENT, TYPE={etype}, ELSET=EM{m}")
        for k in ids:
            lines.append(f"{k + 1}, " + ", ".join(str(i + 1) for i in elems[k]))
    for m, mat in enumerate(problem.materials):
        if m not in problem.element_materials:
            continue
        lines.append(f"*MATERIAL, NAME=M{m}")
        lines.extend(elastic_card(mat, dim, problem.plane, scale))
        lines.append(f"*SOLID SECTION, ELSET=EM{m}, MATERIAL=M{m}")
        if dim == 2:
            lines.append(fnum(problem.thickness))
    if nonlinear:
        lines += ["*STEP, NLGEOM, INC=1000",
                  "*STATIC",
                  "1.0, 1.0, 1.e-6, 1.0",
                  "*CONTROLS, PARAMETERS=TIME INCREMENTATION",
                  NLGEOM_TIME_CONTROLS,
                  "*CONTROLS, PARAMETERS=FIELD",
                  NLGEOM_FIELD_CONTROLS]
    else:
        lines += ["*STEP", "*STATIC"]
    bcs = []
    for i in sorted(case.constraints):
        for d, v in sorted(case.constraints[i].items()):
            if v == 0.0:
                bcs.append(f"{i + 1}, {d + 1}, {d + 1}")
            else:
                bcs.append(f"{i + 1}, {d + 1}, {d + 1}, {fnum(v)}")
    if bcs:
        lines.append("*BOUNDARY")
        lines.extend(bcs)
    loads = []
    for i in sorted(case.forces):
        held = case.constraints.get(i, {})
        for d, v in enumerate(case.forces[i]):
            if v != 0.0 and d not in held:  # a force on a held component is a reaction
                loads.append(f"{i + 1}, {d + 1}, {fnum(v * scale)}")
    if loads:
        lines.append("*CLOAD")
        lines.extend(loads)
    lines += ["*NODE PRINT, NSET=NALL", "U", "*END STEP", ""]
    return "\n".join(lines)
