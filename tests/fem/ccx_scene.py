"""Scene reading for the ccx harness (ccx_reference.py): a springfit scene with a reference of
type fem (proto/SCENE.md) to a Problem (problem_from_scene), with its tractions resolved into
consistent nodal forces (traction_forces, on the mesh's boundary_facets) and anything the
harness does not model refused (SceneError). Python 3 standard library only.
"""

import math

from ccx_problem import LoadCase, Material, Problem, SceneError


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
