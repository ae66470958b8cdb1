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

Exit status: 0 on success, 1 when ccx fails (its message is printed), 2 on an invalid scene
or usage, 3 when ccx is not installed.
"""

import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile

CCX_MISSING = "ccx (CalculiX) not found: run scripts/install-deps.sh"
CCX_TIMEOUT = 300.0  # seconds for one ccx run

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


class SceneError(Exception):
    """The scene cannot be turned into a CalculiX model."""


class CcxError(Exception):
    """ccx failed or its output could not be read."""


class CcxMissing(Exception):
    pass


# ----------------------------------------------------------------------------------------
# Model


class Material:
    def __init__(self, model, young, poisson):
        self.model = model
        self.young = float(young)
        self.poisson = float(poisson)

    def lame(self):
        e, nu = self.young, self.poisson
        lam = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
        mu = e / (2.0 * (1.0 + nu))
        return lam, mu


class LoadCase:
    """constraints: {node: {dof: value}} (dof 0-based); forces: {node: [f0, f1(, f2)]}."""

    def __init__(self, name="", constraints=None, forces=None):
        self.name = name
        self.constraints = constraints if constraints is not None else {}
        self.forces = forces if forces is not None else {}


class Problem:
    """A linear-triangle (2D) or linear-tetrahedron (3D) FEM problem, 0-based node indices.

    plane: "stress" or "strain" (2D only). element_materials[e] indexes materials.
    """

    def __init__(self, nodes, elements, materials, element_materials, cases,
                 plane="stress", thickness=1.0, name=""):
        self.nodes = [[float(c) for c in p] for p in nodes]
        self.dim = len(self.nodes[0])
        self.elements = [list(e) for e in elements]
        self.materials = materials
        self.element_materials = list(element_materials)
        self.cases = cases
        self.plane = plane
        self.thickness = float(thickness)
        self.name = name

    def nonlinear(self):
        models = {self.materials[m].model for m in set(self.element_materials)}
        if "neo_hookean" in models:
            raise SceneError("material model neo_hookean is not compared with ccx "
                             "(only linear and st_venant_kirchhoff)")
        if len(models) > 1:
            raise SceneError("materials mix linear and st_venant_kirchhoff: ccx runs one "
                             "analysis type (NLGEOM or not) for the whole model")
        return models == {"st_venant_kirchhoff"}


# ----------------------------------------------------------------------------------------
# Scene reading


def _is_int(v):
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num(v):
    return (isinstance(v, (int, float)) and not isinstance(v, bool)
            and math.isfinite(float(v)))


def _node_list(value, where, node_sets, n):
    """A node list, or a string naming an entry of the top-level node_sets."""
    if isinstance(value, str):
        if value not in node_sets:
            raise SceneError(f"{where}: unknown node set '{value}'")
        where = f"node_sets.{value}"
        value = node_sets[value]
    if not isinstance(value, list):
        raise SceneError(f"{where}: expected a list of node indices or a node set name")
    out = []
    for k, i in enumerate(value):
        if not _is_int(i):
            raise SceneError(f"{where}[{k}]: expected a node index")
        if not 0 <= i < n:
            raise SceneError(f"{where}[{k}]: node index {i} out of range [0, {n})")
        out.append(i)
    return out


def _vector(value, where, dim):
    if not isinstance(value, list) or len(value) != dim or not all(_is_num(c) for c in value):
        raise SceneError(f"{where}: expected {dim} numbers")
    return [float(c) for c in value]


def _material(obj, where):
    if not isinstance(obj, dict):
        raise SceneError(f"{where}: expected an object")
    model = obj.get("model", "linear")
    if model not in ("linear", "st_venant_kirchhoff", "neo_hookean"):
        raise SceneError(f"{where}.model: unknown material model '{model}'")
    young, poisson = obj.get("young"), obj.get("poisson")
    if not _is_num(young) or young <= 0:
        raise SceneError(f"{where}.young: expected a number > 0")
    if not _is_num(poisson) or not -1.0 < poisson <= 0.5:
        raise SceneError(f"{where}.poisson: expected a number in (-1, 0.5]")
    return Material(model, young, poisson)


def problem_from_scene(scene):
    """Builds a Problem from a parsed scene (dict)."""
    if not isinstance(scene, dict):
        raise SceneError("(top level): expected an object")
    nodes = scene.get("nodes")
    if not isinstance(nodes, list) or not nodes:
        raise SceneError("nodes: expected a non-empty array")
    dim = len(nodes[0]) if isinstance(nodes[0], list) else 0
    if dim not in (2, 3):
        raise SceneError("nodes[0]: a node has 2 or 3 coordinates")
    pts = [_vector(p, f"nodes[{i}]", dim) for i, p in enumerate(nodes)]
    n = len(pts)
    node_sets = scene.get("node_sets", {})
    if not isinstance(node_sets, dict):
        raise SceneError("node_sets: expected an object")

    ref = scene.get("reference")
    if not isinstance(ref, dict) or ref.get("type") != "fem":
        raise SceneError("reference: expected an object with type fem")
    elements = ref.get("elements")
    per = dim + 1
    if not isinstance(elements, list) or not elements:
        raise SceneError("reference.elements: expected a non-empty array")
    elems = []
    for k, e in enumerate(elements):
        where = f"reference.elements[{k}]"
        if not isinstance(e, list) or len(e) != per:
            raise SceneError(f"{where}: expected {per} node indices "
                             f"({'triangles' if dim == 2 else 'tetrahedra'})")
        elems.append(_node_list(e, where, {}, n))
        if len(set(e)) != per:
            raise SceneError(f"{where}: repeated node")

    if "material" in ref and "materials" in ref:
        raise SceneError("reference: give material or materials, not both")
    if "materials" in ref:
        mats = ref["materials"]
        if not isinstance(mats, list) or not mats:
            raise SceneError("reference.materials: expected a non-empty array")
        materials = [_material(m, f"reference.materials[{i}]") for i, m in enumerate(mats)]
        em = ref.get("element_materials")
        if not isinstance(em, list) or len(em) != len(elems):
            raise SceneError(f"reference.element_materials: expected one material index per "
                             f"element ({len(elems)})")
        for k, m in enumerate(em):
            if not _is_int(m) or not 0 <= m < len(materials):
                raise SceneError(f"reference.element_materials[{k}]: material index out of "
                                 f"range [0, {len(materials)})")
        element_materials = list(em)
    else:
        if "element_materials" in ref:
            raise SceneError("reference.element_materials: only applies with materials")
        materials = [_material(ref.get("material"), "reference.material")]
        element_materials = [0] * len(elems)

    plane = ref.get("plane", "stress")
    thickness = ref.get("thickness", 1.0)
    if dim == 3 and ("plane" in ref or "thickness" in ref):
        raise SceneError("reference: plane and thickness only apply to 2D scenes")
    if plane not in ("stress", "strain"):
        raise SceneError("reference.plane: expected stress or strain")
    if not _is_num(thickness) or thickness <= 0:
        raise SceneError("reference.thickness: expected a number > 0")
    if not (dim == 2 and plane == "stress"):
        for m, mat in enumerate(materials):
            if mat.poisson >= 0.5:
                raise SceneError(f"reference.material{'s[%d]' % m if 'materials' in ref else ''}"
                                 f".poisson: 0.5 (incompressible) needs plane stress")

    raw_cases = scene.get("load_cases")
    if not isinstance(raw_cases, list) or not raw_cases:
        raise SceneError("load_cases: expected a non-empty array")
    cases = []
    facets = None  # the mesh's boundary facets, found when a traction first needs them
    for k, c in enumerate(raw_cases):
        where = f"load_cases[{k}]"
        if not isinstance(c, dict):
            raise SceneError(f"{where}: expected an object")
        _check_fields(c, LOAD_CASE_FIELDS, where)
        case = LoadCase(c.get("name", ""))
        for i in _node_list(c.get("fixed", []), f"{where}.fixed", node_sets, n):
            case.constraints[i] = {d: 0.0 for d in range(dim)}
        for j, entry in enumerate(c.get("displacements", [])):
            w = f"{where}.displacements[{j}]"
            targets = _entry_nodes(entry, w, node_sets, n, ENTRY_FIELDS["displacements"])
            disp = _vector(entry.get("displacement"), f"{w}.displacement", dim)
            for i in targets:
                if i in case.constraints:
                    raise SceneError(f"{w}: node {i} is already fixed or displaced")
                case.constraints[i] = {d: disp[d] for d in range(dim)}
        for j, entry in enumerate(c.get("forces", [])):
            w = f"{where}.forces[{j}]"
            targets = _entry_nodes(entry, w, node_sets, n, ENTRY_FIELDS["forces"])
            f = _vector(entry.get("force"), f"{w}.force", dim)
            for i in targets:
                if i in case.constraints:
                    raise SceneError(f"{w}: node {i} is constrained; forces go on free nodes")
                acc = case.forces.setdefault(i, [0.0] * dim)
                for d in range(dim):
                    acc[d] += f[d]
        tractions = c.get("tractions", [])
        if not isinstance(tractions, list):
            raise SceneError(f"{where}.tractions: expected an array")
        for j, entry in enumerate(tractions):
            if facets is None:
                facets = boundary_facets(elems)
            w = f"{where}.tractions[{j}]"
            for i, f in traction_forces(entry, w, pts, facets, node_sets).items():
                if i in case.constraints:
                    continue  # the support takes this share
                acc = case.forces.setdefault(i, [0.0] * dim)
                for d in range(dim):
                    acc[d] += f[d]
        _check_rigid_motion(pts, case, where)
        cases.append(case)
    return Problem(pts, elems, materials, element_materials, cases, plane, thickness,
                   scene.get("name", ""))


def _check_rigid_motion(pts, case, where):
    """springfit's rule (SCENE.md): at least two constrained nodes in 2D, three not on one line
    in 3D. ccx does not detect a singular stiffness: it would print huge displacements."""
    held = sorted(case.constraints)
    dim = len(pts[0])
    if dim == 2:
        if len(held) < 2:
            raise SceneError(f"{where}: rigid motion is left free: a load case needs at least "
                             f"two constrained (fixed or displaced) nodes")
        return
    lo = [min(p[d] for p in pts) for d in range(3)]
    hi = [max(p[d] for p in pts) for d in range(3)]
    extent2 = sum((b - a) ** 2 for a, b in zip(lo, hi))
    if len(held) >= 3:
        a, b = pts[held[0]], pts[held[1]]
        ab = [b[d] - a[d] for d in range(3)]
        for i in held[2:]:
            ac = [pts[i][d] - a[d] for d in range(3)]
            cross = [ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2],
                     ab[0] * ac[1] - ab[1] * ac[0]]
            if math.sqrt(sum(c * c for c in cross)) > 1e-9 * extent2:
                return
    raise SceneError(f"{where}: rigid motion is left free: a load case needs at least three "
                     f"constrained (fixed or displaced) nodes not on one line")


# The fields of a load case and of its entries (proto/SCENE.md, "Load cases"). Anything else
# is refused: a field this harness does not know might change the mechanics.
LOAD_CASE_FIELDS = ("name", "fixed", "forces", "displacements", "tractions")
ENTRY_FIELDS = {"forces": ("node", "nodes", "force"),
                "displacements": ("node", "nodes", "displacement")}


def _check_fields(obj, allowed, where):
    for key in obj:
        if key not in allowed:
            raise SceneError(f"{where}.{key}: unknown field (expected one of: "
                             f"{', '.join(allowed)}); the ccx harness refuses what it does not "
                             f"model rather than ignore it")


def boundary_facets(elements):
    """The boundary facets of a mesh of simplices: the facets (edges of triangles, triangles of
    tetrahedra) that belong to exactly one element, as sorted node tuples."""
    count = {}
    for e in elements:
        for skip in range(len(e)):
            key = tuple(sorted(e[a] for a in range(len(e)) if a != skip))
            count[key] = count.get(key, 0) + 1
    return sorted(f for f, c in count.items() if c == 1)


def facet_measure(pts):
    """Length of an edge (2 points) or area of a triangle (3 points in 3D)."""
    if len(pts) == 2:
        return math.dist(pts[0], pts[1])
    u = [pts[1][d] - pts[0][d] for d in range(3)]
    v = [pts[2][d] - pts[0][d] for d in range(3)]
    cross = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    return 0.5 * math.sqrt(sum(c * c for c in cross))


def traction_forces(entry, where, pts, facets, node_sets):
    """The consistent nodal forces {node: [f0, f1(, f2)]} of one traction entry
    {"on": SET, "total" | "per_length" (2D) | "per_area" (3D): vector}, on every node of the
    loaded facets (constrained ones included: the caller drops those)."""
    dim = len(pts[0])
    density = "per_length" if dim == 2 else "per_area"
    if not isinstance(entry, dict):
        raise SceneError(f"{where}: expected an object")
    _check_fields(entry, ("on", "total", density), where)
    on = entry.get("on")
    if on is None:
        raise SceneError(f"{where}.on: required")
    if not isinstance(on, str):
        raise SceneError(f"{where}.on: expected the name of a node set")
    members = set(_node_list(on, f"{where}.on", node_sets, len(pts)))
    if ("total" in entry) == (density in entry):
        raise SceneError(f'{where}: needs exactly one of "total" or "{density}"')
    key = "total" if "total" in entry else density
    vec = _vector(entry[key], f"{where}.{key}", dim)
    loaded = [f for f in facets if all(i in members for i in f)]
    if not loaded:
        raise SceneError(f"{where}.on: node set '{on}' holds no boundary "
                         f"{'edge' if dim == 2 else 'face'} of the mesh")
    measures = [facet_measure([pts[i] for i in f]) for f in loaded]
    if key == "total":
        t = [v / math.fsum(measures) for v in vec]
    else:
        t = vec
    out = {}
    for f, a in zip(loaded, measures):
        for i in f:
            acc = out.setdefault(i, [0.0] * dim)
            for d in range(dim):
                acc[d] += t[d] * a / len(f)
    return out


def _entry_nodes(entry, where, node_sets, n, fields):
    if not isinstance(entry, dict):
        raise SceneError(f"{where}: expected an object")
    _check_fields(entry, fields, where)
    if ("node" in entry) == ("nodes" in entry):
        raise SceneError(f'{where}: needs exactly one of "node" or "nodes"')
    if "node" in entry:
        return _node_list([entry["node"]], f"{where}.node", node_sets, n)
    return _node_list(entry["nodes"], f"{where}.nodes", node_sets, n)


# ----------------------------------------------------------------------------------------
# Deck writing


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


# ----------------------------------------------------------------------------------------
# Running ccx and reading its output


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
