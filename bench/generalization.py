#!/usr/bin/env python3
"""Generalisation of identified models (issue 31): an independent evaluator that judges each
model on load families the identification never saw, beside the closed-form baseline and the
best one model on the mesh edges for each family alone.

    /usr/bin/python3 bench/generalization.py [SCENE ...] [--springfit build/client/springfit]
        [--run-args "--threads 1"] [--model MODEL.json ...] [--seed 20261126]
        [--pushed 20] [--patches 30] [--train-factor 3] [--skip-best] [--best-seconds 120]
        [--best-evaluations 5000] [--eig-max-dofs 5000] [--unnamed-supports 0] [--no-checks]
        [--json OUT.json] [--keep DIR]

Run it with Debian's python (/usr/bin/python3: numpy, and scipy from python3-scipy, which
scripts/install-deps.sh installs). Default scenes: the five FEM examples.

Per scene the model is `springfit run SCENE -o RESULT.json` (plus --run-args) exported with
`springfit export RESULT.json -o MODEL.json` (proto/MODEL.md), in a temporary directory, or
the files given with --model (one per scene, in order: a model JSON or a `run -o` result).
Nothing else of springfit is used for the physics: this script assembles

  - K_F, the linear FEM stiffness of the scene's reference: linear triangles (plane stress or
    plane strain, times the thickness) or linear tetrahedra, isotropic E and nu per element.
    St. Venant-Kirchhoff and neo-Hookean materials are taken at their small-strain limit
    (the same E and nu): every response here is linear;
  - K_M = sum_e k_e n_e n_e^T on the blocks of the spring's nodes (n_e its unit rest
    direction): the mass-spring model linearised at rest;
  - the closed-form baseline of van Gelder (1998) on the mesh edges:
    k_ij = sum over the elements T on edge ij of E_T |T| / l_ij^2, |T| = area x thickness (2D)
    or volume (3D).

Loads are drawn by this script's own generator (numpy default_rng(--seed), independent of
springfit's probes), on each distinct support (the constrained nodes of a named load case;
the generated families hold them at rest):

  pushed      one free boundary node pushed in: a point force along the inward normal (the
              boundary: edges/faces of one element only; a node's normal: the measure-weighted
              mean of its facets' outward normals); --pushed nodes per support (all of
              them where the support leaves fewer free boundary nodes);
  gravity     a uniform body force, lumped to the nodes by element measure / (d + 1); along -y
              and +x (2D), -z, +x and +y (3D);
  traction45  each named case's nodal forces (tractions resolved to consistent nodal forces)
              turned by +45 and -45 degrees: in 2D in the plane; in 3D about two axes
              perpendicular to the case's resultant force (a random one a and f x a), so that
              the resultant turns by exactly 45 degrees, four loads per case;
  patch       a random free boundary node and its nearest free boundary nodes (3 to 8 in
              all), one random-direction force spread equally on them; --patches per support;
  named       the scene's own load cases (prescribed displacements included).

Every generated load is scaled to the named cases' typical size (the median over them of the
sum of |f_i|); under linear responses the scale does not change E. E of one load is
sqrt(sum_i |u_M,i - u_F,i|^2 / sum_i |u_F,i|^2) over the free nodes; a model whose stiffness
on a support's free DOFs is singular (Jacobi-scaled pivot <= 1e-12: a mechanism) has E = inf
on every load of that support.

Per family: median and 95th percentile of E for the springfit model, the baseline and the best
one model on the mesh edges for that family alone: stiffness k >= 0 on the mesh edges, started
from the baseline, minimising sum over a training draw of the family of
|u_M - u_F|^2 / |u_F|^2 (adjoint gradient, du/dk_e = -K_M^-1 g_e (g_e . u_M)) by L-BFGS-B and
then, up to 2,000 edges, a projected Levenberg-Marquardt with the exact Gauss-Newton matrix;
bounded by --best-seconds and --best-evaluations per family (a local minimum, or where the
bound stopped it: an upper bound on the best), and judged on the evaluation draw. The random
families train on a draw of their own stream, --train-factor times larger (pushed: at most
every free boundary node, so it may include the evaluated ones; patch; traction45 in 3D, new
axes); the deterministic ones (gravity, traction45 in 2D, named) have only one draw: their best
is fitted to the loads it is judged on. The targets of issue 31 are checked per family on both
statistics: springfit / baseline <= 0.5 and springfit / best <= 2. Also, per support, the
extreme generalised eigenvalues of (K_M, K_F) on the free DOFs (dense, up to --eig-max-dofs
free DOFs), how many lie below 0.5 and above 2, and the bound they give on the relative
energy-norm error of every load on that support, max_i |1/lambda_i - 1|.

Supports the user did not name (issue 50: E <= 0.5 x baseline on every family there), with
--unnamed-supports N (default 0: none, and the report is the one above alone): per scene, N
supports drawn by a stream of this script's generator of their own (support i the same for
every N > i), each holding every DOF of its nodes at rest, the kinds in turn (B: the number of
boundary nodes; "the m nearest to node c": the m boundary nodes of least Euclidean distance
to c, c itself first; counts rounded, at least 1):

  third       a third of the boundary held: the round(B / 3) nearest to a random boundary node;
  arc         a random arc (a patch in 3D): a fraction drawn uniformly in [0.1, 0.3] of B, the
              round(fraction x B) nearest to a random boundary node;
  two-sided   two patches of round(B / 10) each: the nearest to a random boundary node c and
              the nearest to the boundary node farthest from c.

A draw is made again (up to UNNAMED_TRIES times, then the support is left out, with a note)
when it does not hold the FEM (K_F on its free DOFs singular: a Jacobi-scaled pivot <= 1e-12),
when its nodes lie nearly on one line in 3D (the second singular value of their centred
positions below COLLINEAR times the first: the rotation about that line all but free), or
when it is a support already named or drawn. On these supports the families pushed, gravity
and patch (drawn as above, on streams of their own; traction45 and named belong to the named
cases and are left out) are reported as pushed@unnamed, gravity@unnamed and patch@unnamed,
pooled over the scene's unnamed supports, in a table of their own with the same columns and
targets; their best fits are made as above, on the unnamed supports' training draws (none with
--skip-best). Per unnamed support: its kind, its held and boundary node counts, whether each
model is a mechanism on it (E = inf on its loads), in how many pieces its nodes lie on the
boundary (joined by the boundary facets' edges: the Euclidean nearest need not be one piece
on a curved boundary), the median E of each model over its loads,
and its generalised eigenvalues as above (up to --eig-max-dofs); unless --no-checks, the FEM
solves' residual on the free DOFs, max over the loads of |K_ff u_f - f_f| / |f_f|.

Sanity checks (unless --no-checks): this FEM against `springfit reference SCENE --json` on
the named cases (max |u - u_springfit| / max |u_springfit|; a scene with a nonlinear
material is compared at 1e-5 of its loads), the nodal forces resolved from the tractions
against that command's, and the E of the baseline and of the model on the named cases
(pooled over the cases) against the run's result JSON (`baseline`, `rms_error`).
"""
import argparse
import contextlib
import json
import math
import os
import platform
import shlex
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field, replace

# L-BFGS-B (Fortran) writes a note on standard output when it restarts a line search. Its
# output unit is made unbuffered (libgfortran reads this when it loads, with numpy's LAPACK)
# so that `fortran_output_silenced` can send the note to /dev/null, away from the report.
os.environ.setdefault("GFORTRAN_UNBUFFERED_PRECONNECTED", "y")

import numpy as np  # noqa: E402
import scipy  # noqa: E402
import scipy.linalg  # noqa: E402
import scipy.optimize  # noqa: E402
import scipy.sparse as sp  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402

DEFAULT_SCENES = ["examples/fem-plate-5x5.json", "examples/fem-kidney-2d.json",
                  "examples/fem-kidney-2d-nl.json", "examples/fem-kidney-2d-fine.json",
                  "examples/fem-block-3d.json"]
FAMILIES = ["pushed", "gravity", "traction45", "patch", "named"]
MECHANISM_PIVOT = 1e-12          # Jacobi-scaled pivot at or below which K is singular
SMALL_LOAD = 1e-5                # the load fraction for the check of a nonlinear reference
UNNAMED_KINDS = ["third", "arc", "two-sided"]      # --unnamed-supports, in turn
UNNAMED_FAMILIES = ["pushed", "gravity", "patch"]  # the families on them
UNNAMED_TRIES = 20               # draws of one unnamed support before it is left out
COLLINEAR = 0.05                 # 3D: sigma_2 / sigma_1 of the held nodes below it: a line
UNNAMED_STREAM = len(FAMILIES)   # the generator's stream of the unnamed supports


# ----------------------------------------------------------------------------------------
# The scene

@dataclass
class Case:
    """A load on one support: nodal forces and prescribed displacements (n x d each)."""
    name: str
    support: int                  # index into Mesh.supports
    force: np.ndarray
    prescribed: np.ndarray


@dataclass
class Mesh:
    name: str
    nodes: np.ndarray             # n x d rest positions
    elements: np.ndarray          # ne x (d + 1)
    young: np.ndarray             # per element
    poisson: np.ndarray           # per element
    plane: str                    # "stress" or "strain" (2D)
    thickness: float              # 2D
    material_models: list
    node_sets: dict
    supports: list = field(default_factory=list)   # sorted tuples of constrained nodes
    named: list = field(default_factory=list)      # Case per named load case

    @property
    def dim(self):
        return self.nodes.shape[1]

    @property
    def linear(self):
        return all(m == "linear" for m in self.material_models)


def node_list(value, node_sets):
    """A list of node indices, or a node set's name standing for one."""
    return list(node_sets[value]) if isinstance(value, str) else list(value)


def entry_nodes(entry, node_sets):
    """The nodes of a force or displacement entry ("node" or "nodes")."""
    return [entry["node"]] if "node" in entry else node_list(entry["nodes"], node_sets)


def read_scene(path):
    """The scene's mesh, material and named load cases (forces from tractions resolved)."""
    with open(path) as f:
        s = json.load(f)
    ref = s["reference"]
    if ref.get("type") != "fem":
        raise SystemExit("%s: not an FEM reference" % path)
    elements = np.array(ref["elements"], dtype=int)
    if "material" in ref:
        materials = [ref["material"]]
        element_materials = np.zeros(len(elements), dtype=int)
    else:
        materials = ref["materials"]
        element_materials = np.array(ref["element_materials"], dtype=int)
    mesh = Mesh(name=s.get("name") or os.path.basename(path),
                nodes=np.array(s["nodes"], dtype=float), elements=elements,
                young=np.array([materials[i]["young"] for i in element_materials], float),
                poisson=np.array([materials[i]["poisson"] for i in element_materials], float),
                plane=ref.get("plane", "stress"), thickness=float(ref.get("thickness", 1.0)),
                material_models=sorted({m["model"] for m in materials}),
                node_sets=s.get("node_sets", {}))
    facets, _, areas = boundary_facets(mesh)
    n, d = mesh.nodes.shape
    for k, lc in enumerate(s["load_cases"]):
        prescribed = np.zeros((n, d))
        constrained = set(node_list(lc.get("fixed", []), mesh.node_sets))
        for entry in lc.get("displacements", []):
            for i in entry_nodes(entry, mesh.node_sets):
                constrained.add(i)
                prescribed[i] = entry["displacement"]
        force = np.zeros((n, d))
        for entry in lc.get("forces", []):
            for i in entry_nodes(entry, mesh.node_sets):
                force[i] += entry["force"]
        for t in lc.get("tractions", []):
            force += traction_forces(mesh, facets, areas, t)
        force[sorted(constrained)] = 0.0      # a share on a held node goes to the support
        support = tuple(sorted(constrained))
        if support not in mesh.supports:
            mesh.supports.append(support)
        mesh.named.append(Case(lc.get("name", "case %d" % k), mesh.supports.index(support),
                               force, prescribed))
    return mesh


# ----------------------------------------------------------------------------------------
# Mesh geometry

def element_geometry(mesh):
    """Shape-function gradients (ne x (d+1) x d) and measures (area x thickness, or volume)."""
    x = mesh.nodes[mesh.elements]                      # ne x (d+1) x d
    edges = x[:, 1:, :] - x[:, :1, :]                  # rows: x_a - x_0
    inverse = np.linalg.inv(edges)                     # column a: grad of N_a (a = 1..d)
    grads = np.empty_like(x)
    grads[:, 1:, :] = np.transpose(inverse, (0, 2, 1))
    grads[:, 0, :] = -grads[:, 1:, :].sum(axis=1)
    measure = np.abs(np.linalg.det(edges)) / math.factorial(mesh.dim)
    if mesh.dim == 2:
        measure = measure * mesh.thickness
    return grads, measure


def local_facets(d):
    """Each facet of a simplex as (its local nodes, the opposite local node)."""
    if d == 2:
        return [((0, 1), 2), ((1, 2), 0), ((2, 0), 1)]
    return [((0, 1, 2), 3), ((0, 1, 3), 2), ((0, 2, 3), 1), ((1, 2, 3), 0)]


def boundary_facets(mesh):
    """Boundary facets (in one element only), their outward normals and their measures."""
    d = mesh.dim
    faces, opposite = [], []
    for local, opp in local_facets(d):
        faces.append(mesh.elements[:, list(local)])
        opposite.append(mesh.elements[:, opp])
    faces = np.concatenate(faces)
    opposite = np.concatenate(opposite)
    _, first, counts = np.unique(np.sort(faces, axis=1), axis=0, return_index=True,
                                 return_counts=True)
    keep = first[counts == 1]
    faces, opposite = faces[keep], opposite[keep]
    x = mesh.nodes
    if d == 2:
        t = x[faces[:, 1]] - x[faces[:, 0]]
        normal = np.stack([t[:, 1], -t[:, 0]], axis=1)          # |normal| = length
    else:
        normal = 0.5 * np.cross(x[faces[:, 1]] - x[faces[:, 0]],
                                x[faces[:, 2]] - x[faces[:, 0]])  # |normal| = area
    inward = np.einsum("fi,fi->f", x[opposite] - x[faces[:, 0]], normal) > 0
    normal[inward] *= -1.0
    return faces, normal, np.linalg.norm(normal, axis=1)


def boundary_normals(mesh):
    """The boundary nodes and their unit outward normals (measure-weighted facet normals)."""
    faces, normal, _ = boundary_facets(mesh)
    summed = np.zeros_like(mesh.nodes)
    for c in range(faces.shape[1]):
        np.add.at(summed, faces[:, c], normal)
    nodes = np.unique(faces)
    return nodes, summed[nodes] / np.linalg.norm(summed[nodes], axis=1)[:, None]


def traction_forces(mesh, facets, areas, traction):
    """Consistent nodal forces of a constant traction on the boundary facets of a node set."""
    members = np.zeros(len(mesh.nodes), dtype=bool)
    members[node_list(traction["on"], mesh.node_sets)] = True
    on = members[facets].all(axis=1)
    if not on.any():
        raise SystemExit("traction on '%s': no boundary facet" % traction["on"])
    if "total" in traction:
        density = np.array(traction["total"], float) / areas[on].sum()
    else:
        density = np.array(traction.get("per_length", traction.get("per_area")), float)
    force = np.zeros_like(mesh.nodes)
    share = areas[on] / facets.shape[1]
    for c in range(facets.shape[1]):
        np.add.at(force, facets[on, c], share[:, None] * density[None, :])
    return force


# ----------------------------------------------------------------------------------------
# Stiffness

def fem_stiffness(mesh):
    """K_F: the linear FEM stiffness (n d x n d, sparse)."""
    grads, measure = element_geometry(mesh)
    e, nu = mesh.young, mesh.poisson
    lam = e * nu / ((1 + nu) * (1 - 2 * nu))
    mu = e / (2 * (1 + nu))
    if mesh.dim == 2 and mesh.plane == "stress":
        lam = 2 * lam * mu / (lam + 2 * mu)
    d = mesh.dim
    eye = np.eye(d)
    # K_ab,ij = V (lam g_ai g_bj + mu g_aj g_bi + mu delta_ij g_a . g_b)
    block = (lam[:, None, None, None, None] * np.einsum("eai,ebj->eaibj", grads, grads)
             + mu[:, None, None, None, None] * np.einsum("eaj,ebi->eaibj", grads, grads)
             + mu[:, None, None, None, None] * np.einsum("eak,ebk->eab", grads, grads)
             [:, :, None, :, None] * eye[None, None, :, None, :])
    block *= measure[:, None, None, None, None]
    dofs = mesh.elements[:, :, None] * d + np.arange(d)[None, None, :]   # ne x (d+1) x d
    rows = np.broadcast_to(dofs[:, :, :, None, None], block.shape)
    cols = np.broadcast_to(dofs[:, None, None, :, :], block.shape)
    size = mesh.nodes.size
    return sp.csr_matrix((block.ravel(), (rows.ravel(), cols.ravel())), shape=(size, size))


def spring_matrix(nodes, pairs):
    """G (n d x m): column e is g_e, +n_e on node i's DOFs and -n_e on node j's."""
    n, d = nodes.shape
    pairs = np.asarray(pairs, dtype=int)
    direction = nodes[pairs[:, 0]] - nodes[pairs[:, 1]]
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    m = len(pairs)
    rows = np.concatenate([pairs[:, 0:1] * d + np.arange(d), pairs[:, 1:2] * d + np.arange(d)],
                          axis=1)
    vals = np.concatenate([direction, -direction], axis=1)
    cols = np.repeat(np.arange(m), 2 * d)
    return sp.csc_matrix((vals.ravel(), (rows.ravel(), cols)), shape=(n * d, m))


def mss_stiffness(g, k):
    """K_M = G diag(k) G^T: the mass-spring model linearised at rest."""
    return (g @ sp.diags(k) @ g.T).tocsr()


def van_gelder(mesh):
    """The closed-form baseline on the mesh edges: (pairs, stiffness)."""
    _, measure = element_geometry(mesh)
    d = mesh.dim
    weights = {}
    for el, vol, young in zip(mesh.elements, measure, mesh.young):
        for a in range(d + 1):
            for b in range(a + 1, d + 1):
                i, j = sorted((int(el[a]), int(el[b])))
                l2 = float(np.sum((mesh.nodes[i] - mesh.nodes[j]) ** 2))
                weights[(i, j)] = weights.get((i, j), 0.0) + young * vol / l2
    pairs = sorted(weights)
    return np.array(pairs, dtype=int), np.array([weights[p] for p in pairs])


# ----------------------------------------------------------------------------------------
# Solves

class Support:
    """The free and constrained DOFs of one support."""

    def __init__(self, constrained, n, d):
        held = np.zeros(n, dtype=bool)
        held[list(constrained)] = True
        dof_held = np.repeat(held, d)
        self.nodes = tuple(constrained)
        self.free = np.flatnonzero(~dof_held)
        self.held = np.flatnonzero(dof_held)


class Factor:
    """A symmetric positive semi-definite K_ff factorised (Jacobi-scaled, SuperLU without
    pivoting off the diagonal); `make` gives None when K_ff is singular: a mechanism (a pivot
    at or below MECHANISM_PIVOT, or none on the diagonal)."""

    def __init__(self, lu, scale):
        self.lu, self.scale = lu, scale

    @classmethod
    def make(cls, kff):
        diag = kff.diagonal()
        if diag.size == 0 or np.min(diag) <= 0 or not np.all(np.isfinite(diag)):
            return None
        scale = 1.0 / np.sqrt(diag)
        scaled = sp.diags(scale) @ kff @ sp.diags(scale)
        try:
            lu = spla.splu(scaled.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True})
        except RuntimeError:                     # exactly singular
            return None
        pivots = lu.U.diagonal()
        if not np.array_equal(lu.perm_r, lu.perm_c) or np.min(pivots) <= MECHANISM_PIVOT:
            return None
        return cls(lu, scale)

    def solve(self, rhs):
        rhs = np.asarray(rhs)
        s = self.scale if rhs.ndim == 1 else self.scale[:, None]
        return s * self.lu.solve(np.ascontiguousarray(s * rhs))


def responses(k_full, support, forces, prescribed):
    """Displacements (n d x L) under the loads (columns of forces and prescribed, n d x L);
    None when K is a mechanism on the support."""
    free, held = support.free, support.held
    factor = Factor.make(k_full[free][:, free])
    if factor is None:
        return None
    u = prescribed.copy()
    rhs = forces[free] - k_full[free][:, held] @ prescribed[held]
    u[free] = factor.solve(rhs)
    return u


def load_errors(u_model, u_ref, free):
    """E of each load (column) over the free DOFs; inf where the model has no response."""
    if u_model is None:
        return np.full(u_ref.shape[1], math.inf)
    diff = np.linalg.norm(u_model[free] - u_ref[free], axis=0)
    return diff / np.linalg.norm(u_ref[free], axis=0)


# ----------------------------------------------------------------------------------------
# Load families

@dataclass
class LoadSet:
    """Loads of one family, grouped by support: per support index, (forces, prescribed)
    as n d x L arrays, and their labels."""
    loads: dict = field(default_factory=dict)
    labels: dict = field(default_factory=dict)

    def add(self, support, label, force, prescribed=None):
        f = force.ravel()
        p = np.zeros_like(f) if prescribed is None else prescribed.ravel()
        fs, ps = self.loads.get(support, (np.zeros((f.size, 0)), np.zeros((f.size, 0))))
        self.loads[support] = (np.column_stack([fs, f]), np.column_stack([ps, p]))
        self.labels.setdefault(support, []).append(label)

    def count(self):
        return sum(f.shape[1] for f, _ in self.loads.values())


def load_scale(mesh):
    """The named cases' typical load: the median of sum_i |f_i| over them (1 if none)."""
    sizes = [np.linalg.norm(c.force, axis=1).sum() for c in mesh.named]
    sizes = [s for s in sizes if s > 0]
    return float(np.median(sizes)) if sizes else 1.0


def scaled(force, scale):
    """The force field scaled to sum_i |f_i| = scale."""
    return force * (scale / np.linalg.norm(force, axis=1).sum())


def random_direction(rng, d):
    """A unit vector uniform on the circle (sphere)."""
    v = rng.normal(size=d)
    return v / np.linalg.norm(v)


def free_boundary(mesh, support):
    """The boundary nodes a support leaves free, and their outward normals."""
    nodes, normals = boundary_normals(mesh)
    keep = ~np.isin(nodes, mesh.supports[support])
    return nodes[keep], normals[keep]


def family_pushed(mesh, rng, count):
    """One free boundary node pushed along its inward normal, `count` nodes per support."""
    out, scale = LoadSet(), load_scale(mesh)
    for s in range(len(mesh.supports)):
        nodes, normals = free_boundary(mesh, s)
        for pick in rng.choice(len(nodes), size=min(count, len(nodes)), replace=False):
            f = np.zeros_like(mesh.nodes)
            f[nodes[pick]] = -normals[pick]
            out.add(s, "node %d" % nodes[pick], scaled(f, scale))
    return out


def family_gravity(mesh):
    """A uniform body force lumped by element measure, along -y, +x (2D) or -z, +x, +y (3D)."""
    out, scale = LoadSet(), load_scale(mesh)
    _, measure = element_geometry(mesh)
    lumped = np.zeros(len(mesh.nodes))
    for c in range(mesh.dim + 1):
        np.add.at(lumped, mesh.elements[:, c], measure / (mesh.dim + 1))
    directions = ({"-y": [0, -1], "+x": [1, 0]} if mesh.dim == 2 else
                  {"-z": [0, 0, -1], "+x": [1, 0, 0], "+y": [0, 1, 0]})
    for s, support in enumerate(mesh.supports):
        for label, g in directions.items():
            f = lumped[:, None] * np.array(g, float)[None, :]
            f[list(support)] = 0.0
            out.add(s, "gravity " + label, scaled(f, scale))
    return out


def rotation(axis, angle):
    """Rodrigues' rotation matrix about a unit axis (3D)."""
    a = axis / np.linalg.norm(axis)
    cross = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * cross + (1 - math.cos(angle)) * cross @ cross


def family_traction45(mesh, rng):
    """Each named case's nodal forces turned by +-45 degrees (3D: about two axes
    perpendicular to its resultant, a random a and f x a)."""
    out, angle = LoadSet(), math.pi / 4
    for case in mesh.named:
        if not np.any(case.force):
            continue                              # displacement-only: nothing to turn
        if mesh.dim == 2:
            turns = [("+45", angle), ("-45", -angle)]
            for label, a in turns:
                r = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
                out.add(case.support, "%s %s" % (case.name, label), case.force @ r.T)
            continue
        resultant = case.force.sum(axis=0)
        if np.linalg.norm(resultant) < 1e-12 * np.linalg.norm(case.force, axis=1).sum():
            resultant = case.force[np.argmax(np.linalg.norm(case.force, axis=1))]
        f_hat = resultant / np.linalg.norm(resultant)
        a = random_direction(rng, 3)
        a -= f_hat * (a @ f_hat)
        a /= np.linalg.norm(a)
        for name, axis in (("a", a), ("f x a", np.cross(f_hat, a))):
            for label, t in (("+45", angle), ("-45", -angle)):
                out.add(case.support, "%s %s about %s" % (case.name, label, name),
                        case.force @ rotation(axis, t).T)
    return out


def family_patch(mesh, rng, count):
    """A random free boundary node and its nearest free boundary nodes (3 to 8 in all), one
    random-direction force spread equally on them; `count` patches per support."""
    out, scale = LoadSet(), load_scale(mesh)
    for s in range(len(mesh.supports)):
        nodes, _ = free_boundary(mesh, s)
        for _ in range(count):
            centre = mesh.nodes[nodes[rng.integers(len(nodes))]]
            size = min(int(rng.integers(3, 9)), len(nodes))
            nearest = nodes[np.argsort(np.linalg.norm(mesh.nodes[nodes] - centre, axis=1),
                                       kind="stable")[:size]]
            f = np.zeros_like(mesh.nodes)
            f[nearest] = random_direction(rng, mesh.dim)
            out.add(s, "patch at %d (%d nodes)" % (nearest[0], size), scaled(f, scale))
    return out


def family_named(mesh):
    """The scene's own load cases."""
    out = LoadSet()
    for case in mesh.named:
        out.add(case.support, case.name, case.force, case.prescribed)
    return out


def draw_family(mesh, family, seed, stream, args, unnamed=False):
    """A draw of one family; `stream` 0 is the evaluation draw, 1 the best fit's training
    draw (--train-factor times as many pushed nodes and patches). None for the training draw
    of a family that has only one (the evaluation's). `unnamed`: on the unnamed supports
    (mesh.supports those), from streams of their own."""
    rng = np.random.default_rng([seed, FAMILIES.index(family), stream]
                                + ([UNNAMED_STREAM] if unnamed else []))
    factor = args.train_factor if stream == 1 else 1
    if family == "pushed":
        return family_pushed(mesh, rng, args.pushed * factor)
    if family == "patch":
        return family_patch(mesh, rng, args.patches * factor)
    if family == "traction45" and (mesh.dim == 3 or stream == 0):
        return family_traction45(mesh, rng)
    if stream == 1:
        return None
    return family_gravity(mesh) if family == "gravity" else family_named(mesh)


def nearest_boundary(mesh, boundary, centre, count):
    """The `count` boundary nodes nearest (Euclidean) to node `centre`, itself first."""
    dist = np.linalg.norm(mesh.nodes[boundary] - mesh.nodes[centre], axis=1)
    return boundary[np.argsort(dist, kind="stable")[:count]]


def unnamed_support(mesh, rng, kind):
    """One draw of an unnamed support of a kind: (held nodes, a description)."""
    boundary, _ = boundary_normals(mesh)
    b = len(boundary)
    centre = int(boundary[rng.integers(b)])
    if kind == "third":
        return nearest_boundary(mesh, boundary, centre, max(1, round(b / 3))), \
            "a third, around node %d" % centre
    if kind == "arc":
        fraction = float(rng.uniform(0.1, 0.3))
        return nearest_boundary(mesh, boundary, centre, max(1, round(fraction * b))), \
            "arc of %.3f, around node %d" % (fraction, centre)
    far = int(boundary[np.argmax(np.linalg.norm(mesh.nodes[boundary] - mesh.nodes[centre],
                                                axis=1))])
    size = max(1, round(b / 10))
    held = np.union1d(nearest_boundary(mesh, boundary, centre, size),
                      nearest_boundary(mesh, boundary, far, size))
    return held, "2 x %d, around nodes %d and %d" % (size, centre, far)


def boundary_pieces(mesh, held):
    """How many pieces the held nodes make on the boundary (joined by boundary facets' edges)."""
    faces = boundary_facets(mesh)[0]
    parent = {int(i): int(i) for i in held}

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a in range(faces.shape[1]):
        for b in range(a + 1, faces.shape[1]):
            for i, j in zip(faces[:, a], faces[:, b]):
                if int(i) in parent and int(j) in parent:
                    parent[root(int(i))] = root(int(j))
    return len({root(i) for i in parent})


def support_fault(mesh, k_fem, held):
    """Why a support does not hold the FEM (None when it does)."""
    if mesh.dim == 3:
        x = mesh.nodes[held] - mesh.nodes[held].mean(axis=0)
        sigma = np.linalg.svd(x, compute_uv=False)
        if len(held) < 3 or sigma[1] <= COLLINEAR * sigma[0]:
            return "nearly collinear"
    sup = Support(held, *mesh.nodes.shape)
    if sup.free.size == 0 or Factor.make(k_fem[sup.free][:, sup.free]) is None:
        return "K_F singular"
    if len(free_boundary(replace(mesh, supports=[tuple(held)]), 0)[0]) == 0:
        return "no free boundary node"
    return None


def draw_unnamed_supports(mesh, k_fem, seed, count):
    """--unnamed-supports: `count` supports, the kinds in turn, each drawn again (up to
    UNNAMED_TRIES times) while it does not hold the FEM or is one named or drawn already.
    Per support: dict(kind, nodes (a sorted tuple), boundary, description, redraws)."""
    rng = np.random.default_rng([seed, UNNAMED_STREAM])
    boundary = len(boundary_normals(mesh)[0])
    out, notes = [], []
    for i in range(count):
        kind = UNNAMED_KINDS[i % len(UNNAMED_KINDS)]
        faults = []
        for _ in range(UNNAMED_TRIES):
            held, text = unnamed_support(mesh, rng, kind)
            nodes = tuple(sorted(int(v) for v in held))
            fault = ("already a support" if nodes in mesh.supports
                     or nodes in [u["nodes"] for u in out]
                     else support_fault(mesh, k_fem, held))
            if fault is None:
                out.append(dict(kind=kind, nodes=nodes, boundary=boundary, description=text,
                                redraws=faults))
                break
            faults.append(fault)
        else:
            notes.append("unnamed support %d (%s): left out, no draw held the FEM in %d (%s)"
                         % (i, kind, UNNAMED_TRIES, ", ".join(sorted(set(faults)))))
    return out, notes


# ----------------------------------------------------------------------------------------
# Evaluation

class Evaluator:
    """The FEM reference's responses to each draw, and E of any model under them."""

    def __init__(self, mesh, k_fem):
        self.mesh, self.k_fem = mesh, k_fem
        n, d = mesh.nodes.shape
        self.supports = [Support(s, n, d) for s in mesh.supports]
        self.fem_factors = []
        for sup in self.supports:
            f = Factor.make(k_fem[sup.free][:, sup.free])
            if f is None:
                raise SystemExit("%s: the FEM is a mechanism on a support" % mesh.name)
            self.fem_factors.append(f)

    def fem_responses(self, loadset):
        """The FEM's displacements (n d x L) per support under a LoadSet."""
        out = {}
        for s, (forces, prescribed) in loadset.loads.items():
            sup = self.supports[s]
            u = prescribed.copy()
            rhs = forces[sup.free] - self.k_fem[sup.free][:, sup.held] @ prescribed[sup.held]
            u[sup.free] = self.fem_factors[s].solve(rhs)
            out[s] = u
        return out

    def errors(self, k_model, loadset, reference):
        """E per load, in the LoadSet's order (support by support)."""
        out = []
        for s, (forces, prescribed) in sorted(loadset.loads.items()):
            u = responses(k_model, self.supports[s], forces, prescribed)
            out.append(load_errors(u, reference[s], self.supports[s].free))
        return np.concatenate(out)

    def pooled(self, k_model, loadset, reference):
        """E pooled over the loads: sqrt(sum |u_M - u_F|^2 / sum |u_F|^2), as springfit's."""
        num = den = 0.0
        for s, (forces, prescribed) in sorted(loadset.loads.items()):
            free = self.supports[s].free
            u = responses(k_model, self.supports[s], forces, prescribed)
            if u is None:
                return math.inf
            num += np.sum((u[free] - reference[s][free]) ** 2)
            den += np.sum(reference[s][free] ** 2)
        return math.sqrt(num / den)


def quantiles(errors):
    """Median and 95th percentile (inf stays inf)."""
    e = np.where(np.isfinite(errors), errors, 1e300)
    med, p95 = np.percentile(e, [50, 95])
    return [math.inf if v >= 1e299 else float(v) for v in (med, p95)]


def generalized_extremes(k_model, k_fem, support):
    """The smallest and largest eigenvalue of (K_M, K_F) on the support's free DOFs, and the
    bound max_i |1/lambda_i - 1| on ||u_M - u_F||_KF / ||u_F||_KF for every load."""
    free = support.free
    a = k_model[free][:, free].toarray()
    b = k_fem[free][:, free].toarray()
    lam = scipy.linalg.eigh(a, b, eigvals_only=True, check_finite=False)
    lo, hi = float(lam[0]), float(lam[-1])
    bound = math.inf if lo <= 0 else max(1 / lo - 1, 1 - 1 / hi)
    return {"lambda_min": lo, "lambda_max": hi, "energy_bound": bound,
            "below_0.5": int(np.sum(lam < 0.5)), "above_2": int(np.sum(lam > 2)),
            "dofs": int(free.size)}


# ----------------------------------------------------------------------------------------
# The best one model on the mesh edges for one family

@contextlib.contextmanager
def fortran_output_silenced():
    """Standard output's file descriptor sent to /dev/null meanwhile (Python's own flushed)."""
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 1)
    try:
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


class EdgeFit:
    """min over k >= 0 of f(k) = 1/2 sum_l |u_M,l(k) - u_F,l|^2 / |u_F,l|^2 over the training
    loads, the springs the mesh edges (columns of G). The gradient is the adjoint one,
    J_l = du_l/dk = -K^-1 G diag(w_l) with w_l = G^T u_l / |u_F,l| (one solve per load).
    From the baseline: L-BFGS-B (variables k / k_baseline) for a share of the time, then, up
    to DENSE_MAX springs, projected Levenberg-Marquardt with the Gauss-Newton matrix J^T J
    built densely, to a local minimum. The two find different local minima from the baseline
    (up to 12% apart on fem-kidney-2d); the first's small steps find the lower. The bound is
    k >= FLOOR x k_baseline rather than 0: the mesh's edges hold every support at any positive
    stiffness (rigidity depends on the directions only), so no step meets a mechanism, which
    would stop L-BFGS-B's line search; a spring at the floor counts as absent."""

    DENSE_MAX = 2000
    FLOOR = 1e-6

    def __init__(self, evaluator, g, loadset):
        self.parts = []
        g = g.tocsr()
        self.springs = g.shape[1]
        reference = evaluator.fem_responses(loadset)
        for s, (forces, prescribed) in sorted(loadset.loads.items()):
            sup = evaluator.supports[s]
            self.parts.append(dict(forces=forces[sup.free], u_held=prescribed[sup.held],
                                   ref=reference[s][sup.free],
                                   norm=np.linalg.norm(reference[s][sup.free], axis=0),
                                   g_free=g[sup.free].tocsc(), g_held=g[sup.held].tocsc()))

    def count(self):
        return sum(len(p["norm"]) for p in self.parts)

    def rms(self, cost):
        """The training E (root mean square of the loads' E) of a cost."""
        return math.sqrt(2 * cost / self.count())

    def state(self, k):
        """The cost at k and, per support, (factor, residuals r, w, G on the free DOFs);
        (inf, None) when k is a mechanism on some support."""
        cost, parts = 0.0, []
        for p in self.parts:
            gk = p["g_free"] @ sp.diags(k)
            factor = Factor.make((gk @ p["g_free"].T).tocsc())
            if factor is None:
                return math.inf, None
            u_free = factor.solve(p["forces"] - (gk @ p["g_held"].T) @ p["u_held"])
            r = (u_free - p["ref"]) / p["norm"]
            w = (p["g_free"].T @ u_free + p["g_held"].T @ p["u_held"]) / p["norm"]
            cost += 0.5 * float(np.sum(r * r))
            parts.append((factor, r, w, p["g_free"]))
        return cost, parts

    @staticmethod
    def gradient(parts):
        """J^T r: one solve per load."""
        return -sum((w * (g.T @ f.solve(r))).sum(axis=1) for f, r, w, g in parts)

    @staticmethod
    def gauss_newton_matrix(parts):
        """J^T J = sum over supports of (Y^T Y) o (sum_l w_l w_l^T), Y = K^-1 G."""
        out = 0.0
        for f, _, w, g in parts:
            y = f.solve(g.toarray())
            out = out + (y.T @ y) * (w @ w.T)
        return out

    def lbfgs(self, k0, deadline, evaluations):
        """L-BFGS-B from k0 until it converges, `evaluations` or the deadline."""
        best, calls = [math.inf, k0], [0]

        class OutOfTime(Exception):
            pass

        def objective(x):
            if time.monotonic() > deadline:
                raise OutOfTime()
            calls[0] += 1
            cost, parts = self.state(x * k0)
            if parts is None:                  # a mechanism: no response to compare
                return 1e300, np.zeros_like(x)
            if cost < best[0]:
                best[:] = [cost, x * k0]
            return cost, self.gradient(parts) * k0

        try:
            with fortran_output_silenced():
                out = scipy.optimize.minimize(
                    objective, np.ones_like(k0), jac=True, method="L-BFGS-B",
                    bounds=[(self.FLOOR, None)] * len(k0),
                    options=dict(maxiter=evaluations, maxfun=evaluations, maxcor=30,
                                 ftol=1e-15, gtol=1e-12))
            converged = bool(out.success)
        except OutOfTime:
            converged = False
        return best[1], converged, calls[0]

    def levenberg_marquardt(self, k, floor, deadline, max_iterations=1000, window=10,
                            tolerance=1e-6):
        """Projected LM from k (bounds k >= floor) until no step lowers the cost, E fell by
        less than `tolerance` (relative) over `window` steps, or the deadline."""
        cost, parts = self.state(k)
        history, mu, iterations = [cost], 1.0, 0
        while iterations < max_iterations and time.monotonic() < deadline:
            iterations += 1
            grad = self.gradient(parts)
            hessian = self.gauss_newton_matrix(parts)
            diag = np.diag(hessian).copy()
            # springs free to move: seen by some load, and not at the floor with the
            # gradient pushing them below it
            movable = (diag > 1e-14 * diag.max()) & ~((k <= floor) & (grad > 0))
            sub = hessian[np.ix_(movable, movable)]
            trial_cost = math.inf
            while mu <= 1e10 and time.monotonic() < deadline:
                trial = k.copy()
                try:
                    factor = scipy.linalg.cho_factor(sub + mu * np.diag(diag[movable]))
                    trial[movable] = np.maximum(
                        k[movable] - scipy.linalg.cho_solve(factor, grad[movable]),
                        floor[movable])
                    trial_cost, trial_parts = self.state(trial)
                except np.linalg.LinAlgError:
                    pass
                if trial_cost < cost:
                    break
                mu *= 8.0
            if trial_cost >= cost:
                return k, iterations, mu > 1e10   # no step lowers the cost: a minimum
            k, cost, parts = trial, trial_cost, trial_parts
            mu = max(mu / 4.0, 1e-6)
            history.append(cost)
            if len(history) > window and \
                    math.sqrt(history[-1 - window] / cost) - 1 < tolerance:
                return k, iterations, True
        return k, iterations, False

    def fit(self, k0, seconds, evaluations):
        """The best stiffness found within `seconds`, and how it was found."""
        start = time.monotonic()
        dense = self.springs <= self.DENSE_MAX
        share = 0.6 if dense else 1.0
        k, lbfgs_converged, used = self.lbfgs(k0, start + share * seconds, evaluations)
        info = dict(lbfgs_evaluations=used, lbfgs_converged=lbfgs_converged,
                    lbfgs_seconds=time.monotonic() - start, lm_iterations=0,
                    start_rms=self.rms(self.state(k0)[0]))
        converged = lbfgs_converged
        if dense:
            k, info["lm_iterations"], converged = self.levenberg_marquardt(
                k, self.FLOOR * k0, start + seconds)
        info.update(converged=converged, final_rms=self.rms(self.state(k)[0]))
        return k, info


# ----------------------------------------------------------------------------------------
# springfit

def run_springfit(args, scene, tmp, index):
    """springfit run + export: (model path, result path, run seconds)."""
    result = os.path.join(tmp, "result-%d.json" % index)
    model = os.path.join(tmp, "model-%d.json" % index)
    cmd = [args.springfit, "run", scene, "-q", "-o", result] + shlex.split(args.run_args)
    start = time.monotonic()
    proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    seconds = time.monotonic() - start
    # 10 unusable (a model that is no answer), 11 unmet_request, 12 doubtful: written still
    if proc.returncode not in (0, 10, 11, 12):
        raise SystemExit("%s failed (%d): %s" % (" ".join(cmd), proc.returncode, proc.stderr))
    subprocess.run([args.springfit, "export", result, "-o", model], check=True,
                   stdout=subprocess.DEVNULL)
    return model, result, seconds


def read_model(path):
    """(pairs, stiffness, result or None) from a model JSON or a `run -o` result."""
    with open(path) as f:
        data = json.load(f)
    if data.get("format") == "springfit-model":
        pairs = [s["nodes"] for s in data["springs"]]
        stiffness = [s["stiffness"] for s in data["springs"]]
        return np.array(pairs, int).reshape(-1, 2), np.array(stiffness, float), None
    return (np.array(data["springs"], int).reshape(-1, 2), np.array(data["stiffness"], float),
            data)


def springfit_reference(args, scene_path, tmp, fraction=1.0):
    """`springfit reference --json` on the scene (its loads scaled by `fraction`)."""
    if fraction != 1.0:
        with open(scene_path) as f:
            scene = json.load(f)
        for lc in scene["load_cases"]:
            for entry in lc.get("forces", []):
                entry["force"] = [fraction * v for v in entry["force"]]
            for entry in lc.get("displacements", []):
                entry["displacement"] = [fraction * v for v in entry["displacement"]]
            for t in lc.get("tractions", []):
                for key in ("total", "per_length", "per_area"):
                    if key in t:
                        t[key] = [fraction * v for v in t[key]]
        scene_path = os.path.join(tmp, "small-load.json")
        with open(scene_path, "w") as f:
            json.dump(scene, f)
    out = subprocess.run([args.springfit, "reference", scene_path, "--json"], check=True,
                         stdout=subprocess.PIPE, text=True).stdout
    return json.loads(out)


def check_reference(args, mesh, scene_path, evaluator, tmp):
    """This FEM's named responses against springfit's reference (and resolved forces)."""
    fraction = 1.0 if mesh.linear else SMALL_LOAD
    solved = springfit_reference(args, scene_path, tmp, fraction)
    named = family_named(mesh)
    mine = evaluator.fem_responses(named)
    order = {s: 0 for s in mine}
    rows = []
    for k, case in enumerate(mesh.named):
        s = case.support
        u = mine[s][:, order[s]].reshape(mesh.nodes.shape) * fraction
        order[s] += 1
        theirs = np.array(solved["reference"]["positions"][k]) - mesh.nodes
        u_diff = np.max(np.linalg.norm(u - theirs, axis=1)) / np.max(np.linalg.norm(theirs,
                                                                                    axis=1))
        force = np.zeros_like(mesh.nodes)
        for entry in solved["load_cases"][k].get("forces", []):
            for i in entry_nodes(entry, mesh.node_sets):
                force[i] += entry["force"]
        f_scale = np.max(np.linalg.norm(case.force, axis=1)) * fraction
        f_diff = (np.max(np.linalg.norm(case.force * fraction - force, axis=1)) / f_scale
                  if f_scale > 0 else 0.0)
        rows.append(dict(case=case.name, displacement=float(u_diff), force=float(f_diff)))
    return dict(load_fraction=fraction, cases=rows,
                max_displacement=max(r["displacement"] for r in rows),
                max_force=max(r["force"] for r in rows))


# ----------------------------------------------------------------------------------------
# Report

def jsonable(x):
    """x with inf and nan written as the strings "inf", "-inf", "nan" (JSON has neither)."""
    if isinstance(x, dict):
        return {k: jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else str(float(x))
    if isinstance(x, np.integer):
        return int(x)
    return x


def machine():
    cpu = "unknown"
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((l.split(":", 1)[1].strip() for l in f if l.startswith("model name")),
                       cpu)
    except OSError:
        pass
    try:
        commit = subprocess.run(["git", "describe", "--always", "--dirty"],
                                capture_output=True, text=True).stdout.strip()
    except OSError:
        commit = ""
    return dict(nproc=os.cpu_count(), cpu=cpu, python=platform.python_version(),
                numpy=np.__version__, scipy=scipy.__version__, commit=commit,
                date=time.strftime("%Y-%m-%d %H:%M"))


def fmt(x):
    if x is None:
        return "-"
    if math.isinf(x):
        return "inf"
    return "%.3g" % x


def ratio(a, b):
    if a is None or b is None:
        return None
    if math.isinf(a):
        return math.inf
    return a / b if b > 0 else math.inf


def print_scene(rep):
    print("\n## %s" % rep["scene"])
    print("%d nodes, %d elements (%s), %s; supports: %s; load scale %.4g" % (
        rep["nodes"], rep["elements"], rep["element_kind"], rep["material"],
        ", ".join("%d held nodes" % n for n in rep["support_sizes"]), rep["load_scale"]))
    print("springfit model: %d springs%s; baseline: van Gelder, %d mesh edges" % (
        rep["model"]["springs"],
        ", run %.1f s" % rep["model"]["run_seconds"] if rep["model"]["run_seconds"] else "",
        rep["baseline_springs"]))
    print_families(rep["families"], FAMILIES)
    for s, eig in enumerate(rep["eigen"]):
        if eig is None:
            print("support %d: eigenvalues skipped (%d free DOFs > --eig-max-dofs)" % (
                s, rep["support_dofs"][s]))
            continue
        print("support %d (%d DOFs): %s" % (s, eig["springfit"]["dofs"], eigen_text(eig)))
    print_checks(rep.get("checks"))
    if "unnamed" in rep:
        print_unnamed(rep["unnamed"])
    print("timing (s): " + ", ".join("%s %.2f" % kv for kv in rep["seconds"].items()))
    sys.stdout.flush()


def eigen_text(eig):
    return ("lambda(K_M, K_F) springfit [%s, %s] bound %s (%d below 0.5, %d above 2); "
            "baseline [%s, %s] bound %s" % (
                fmt(eig["springfit"]["lambda_min"]), fmt(eig["springfit"]["lambda_max"]),
                fmt(eig["springfit"]["energy_bound"]), eig["springfit"]["below_0.5"],
                eig["springfit"]["above_2"], fmt(eig["baseline"]["lambda_min"]),
                fmt(eig["baseline"]["lambda_max"]), fmt(eig["baseline"]["energy_bound"])))


def print_families(families, names):
    """The table of the families `names`, then their best fits."""
    head = ("| family | loads | springfit med / p95 | baseline med / p95 | best med / p95 "
            "| sf/base med, p95 | sf/best med, p95 | targets |")
    print(head)
    print("|---|---:|---|---|---|---|---|---|")
    for fam in names:
        r = families[fam]
        best = r.get("best")
        best_text = ("%s / %s" % (fmt(best["median"]), fmt(best["p95"]))
                     if best else "-")
        rb = [ratio(r["springfit"][q], r["baseline"][q]) for q in ("median", "p95")]
        rbest = [ratio(r["springfit"][q], best[q]) if best else None for q in ("median", "p95")]
        print("| %s | %d | %s / %s | %s / %s | %s | %s, %s | %s, %s | %s |" % (
            fam, r["loads"], fmt(r["springfit"]["median"]), fmt(r["springfit"]["p95"]),
            fmt(r["baseline"]["median"]), fmt(r["baseline"]["p95"]), best_text,
            fmt(rb[0]), fmt(rb[1]), fmt(rbest[0]), fmt(rbest[1]), r["targets"]))
    for fam in names:
        b = families[fam].get("best_fit")
        if b:
            print("best %s: %d training loads%s; L-BFGS-B %s evaluations, LM %d steps, %.1f s, "
                  "%s; training E %.3g -> %.3g, %d of %d springs" % (
                      fam, b["train_loads"], " (the evaluation draw)" if b["in_sample"] else "",
                      b["lbfgs_evaluations"],
                      b["lm_iterations"], b["seconds"],
                      "converged" if b["converged"] else "stopped by its bound",
                      b["start_rms"], b["final_rms"], b["springs"], b["edges"]))


def print_checks(checks):
    if checks:
        ref = checks.get("reference")
        if ref:
            print("check: this FEM vs springfit reference (%s): max |du|/max|u| %.2g, "
                  "resolved forces %.2g" % (
                      "full load" if ref["load_fraction"] == 1 else
                      "at %g of the load" % ref["load_fraction"],
                      ref["max_displacement"], ref["max_force"]))
        for key, label in (("baseline", "baseline"), ("model", "springfit model")):
            c = checks.get(key)
            if c:
                print("check: %s E on the named cases, pooled: here %.6g, springfit's result "
                      "%s (relative difference %.2g%s)" % (
                          label, c["here"],
                          "-" if c["springfit"] is None else "%.6g" % c["springfit"],
                          c["relative_difference"],
                          "" if c["same_response"] else
                          "; springfit's is its nonlinear response to the nonlinear reference"))


def print_unnamed(unnamed):
    """--unnamed-supports: the families on them, then each support."""
    print("unnamed supports (--unnamed-supports %d, drawn here; E over every unnamed support's "
          "loads; target springfit <= 0.5 x baseline):" % unnamed["count"])
    if unnamed["families"]:
        print_families(unnamed["families"], [f + "@unnamed" for f in UNNAMED_FAMILIES])
    for s, u in enumerate(unnamed["supports"]):
        faults = u["redraws"]
        print("unnamed support %d: %s, %d of %d boundary nodes held (%s; %d piece%s), "
              "%d free DOFs%s; %d loads, E med springfit %s%s, baseline %s%s" % (
                  s, u["kind"], u["held"], u["boundary"], u["description"], u["pieces"],
                  "" if u["pieces"] == 1 else "s", u["free_dofs"],
                  "; %d redraws (%s)" % (len(faults), ", ".join(sorted(set(faults))))
                  if faults else "", u["loads"], fmt(u["springfit"]["median"]),
                  " (a mechanism)" if u["springfit"]["mechanism"] else "",
                  fmt(u["baseline"]["median"]),
                  " (a mechanism)" if u["baseline"]["mechanism"] else ""))
        print("  " + ("eigenvalues skipped (> --eig-max-dofs)" if u["eigen"] is None else
                      eigen_text(u["eigen"])))
    for note in unnamed["notes"]:
        print(note)
    if "residual" in unnamed:
        print("check: unnamed supports, FEM solves max |K_ff u_f - f_f| / |f_f| per support: "
              + ", ".join("%.2g" % r for r in unnamed["residual"]))


def family_targets(sf, base, best):
    """Issue 31's targets on one family: springfit <= 0.5 baseline and <= 2 best, on the
    median and the 95th percentile."""
    ok_base = all(ratio(sf[q], base[q]) <= 0.5 for q in ("median", "p95"))
    parts = ["base %s" % ("yes" if ok_base else "NO")]
    if best:
        ok_best = all(ratio(sf[q], best[q]) <= 2 for q in ("median", "p95"))
        parts.append("best %s" % ("yes" if ok_best else "NO"))
    return ", ".join(parts)


# ----------------------------------------------------------------------------------------

def evaluate_family(args, mesh, evaluator, fam, models, seconds, unnamed=False):
    """One family's figures (and its best fit, unless --skip-best) on the evaluator's supports;
    `unnamed`: the unnamed supports' draws, named fam@unnamed, each load with its support."""
    k_model, k_baseline, g_edges, k_base = models
    name = fam + "@unnamed" if unnamed else fam
    t = time.monotonic()
    draw = draw_family(mesh, fam, args.seed, 0, args, unnamed)
    reference = evaluator.fem_responses(draw)
    e_model = evaluator.errors(k_model, draw, reference)
    e_base = evaluator.errors(k_baseline, draw, reference)
    labels = [(s, l) for s in sorted(draw.labels) for l in draw.labels[s]]
    entry = dict(loads=draw.count(),
                 springfit=dict(zip(("median", "p95"), quantiles(e_model)),
                                pooled=evaluator.pooled(k_model, draw, reference)),
                 baseline=dict(zip(("median", "p95"), quantiles(e_base)),
                               pooled=evaluator.pooled(k_baseline, draw, reference)),
                 per_load=[dict(label=l, springfit=float(a), baseline=float(b),
                                **(dict(support=s) if unnamed else {}))
                           for (s, l), a, b in zip(labels, e_model, e_base)])
    seconds["evaluate " + name] = time.monotonic() - t
    if not args.skip_best:
        t = time.monotonic()
        train = draw_family(mesh, fam, args.seed, 1, args, unnamed) or draw
        fitter = EdgeFit(evaluator, g_edges, train)
        k_best, info = fitter.fit(k_base, args.best_seconds, args.best_evaluations)
        k_best_full = mss_stiffness(g_edges, k_best)
        e_best = evaluator.errors(k_best_full, draw, reference)
        entry["best"] = dict(zip(("median", "p95"), quantiles(e_best)),
                             pooled=evaluator.pooled(k_best_full, draw, reference))
        for row, e in zip(entry["per_load"], e_best):
            row["best"] = float(e)
        info.update(train_loads=train.count(), seconds=time.monotonic() - t,
                    in_sample=train is draw,
                    springs=int(np.sum(k_best > 1.001 * EdgeFit.FLOOR * k_base)),
                    edges=len(k_best))
        entry["best_fit"] = info
        seconds["best " + name] = info["seconds"]
    entry["targets"] = family_targets(entry["springfit"], entry["baseline"],
                                      entry.get("best")) if fam != "named" else "(fitted)"
    return entry


def evaluate_unnamed(args, mesh, k_fem, models, seconds):
    """--unnamed-supports: the supports drawn, their families, per support its figures."""
    k_model, k_baseline = models[0], models[1]
    t = time.monotonic()
    drawn, notes = draw_unnamed_supports(mesh, k_fem, args.seed, args.unnamed_supports)
    out = dict(count=args.unnamed_supports, notes=notes, supports=[], families={})
    seconds["unnamed supports"] = time.monotonic() - t
    if not drawn:
        return out
    umesh = replace(mesh, supports=[u["nodes"] for u in drawn])
    evaluator = Evaluator(umesh, k_fem)
    for fam in UNNAMED_FAMILIES:
        out["families"][fam + "@unnamed"] = evaluate_family(args, umesh, evaluator, fam, models,
                                                            seconds, unnamed=True)
    t = time.monotonic()
    for s, (u, sup) in enumerate(zip(drawn, evaluator.supports)):
        rows = [r for f in out["families"].values() for r in f["per_load"] if r["support"] == s]
        row = dict(kind=u["kind"], held=len(u["nodes"]), boundary=u["boundary"],
                   description=u["description"], redraws=u["redraws"], nodes=list(u["nodes"]),
                   free_dofs=int(sup.free.size), loads=len(rows),
                   pieces=boundary_pieces(mesh, u["nodes"]))
        for key, k_full in (("springfit", k_model), ("baseline", k_baseline)):
            row[key] = dict(
                mechanism=Factor.make(k_full[sup.free][:, sup.free]) is None,
                median=quantiles(np.array([r[key] for r in rows]))[0])
        row["eigen"] = (None if sup.free.size > args.eig_max_dofs else
                        dict(springfit=generalized_extremes(k_model, k_fem, sup),
                             baseline=generalized_extremes(k_baseline, k_fem, sup)))
        out["supports"].append(row)
    seconds["unnamed eigenvalues"] = time.monotonic() - t
    if not args.no_checks:
        t = time.monotonic()
        out["residual"] = fem_residual(evaluator, [draw_family(umesh, fam, args.seed, 0, args,
                                                                True)
                                                    for fam in UNNAMED_FAMILIES])
        seconds["unnamed checks"] = time.monotonic() - t
    return out


def fem_residual(evaluator, loadsets):
    """Per support, max over the loads of |K_f. u - f_f| / |f_f| of the FEM's solves (the
    held DOFs at rest: |K_ff u_f - f_f| / |f_f|)."""
    k, worst = evaluator.k_fem, {}
    for loadset in loadsets:
        responses_ = evaluator.fem_responses(loadset)
        for s, (forces, _) in loadset.loads.items():
            sup, u = evaluator.supports[s], responses_[s]
            r = k[sup.free] @ u - forces[sup.free]
            rel = np.linalg.norm(r, axis=0) / np.linalg.norm(forces[sup.free], axis=0)
            worst[s] = max(worst.get(s, 0.0), float(np.max(rel)))
    return [worst[s] for s in sorted(worst)]


def evaluate_scene(args, scene_path, model_path, tmp, index):
    """Every number of one scene: the families, the best fits, eigenvalues, checks."""
    seconds, given = {}, model_path
    t0 = time.monotonic()
    mesh = read_scene(scene_path)
    result, run_seconds = None, None
    if model_path is None:
        model_path, result_path, run_seconds = run_springfit(args, scene_path, tmp, index)
        seconds["springfit run"] = run_seconds
        with open(result_path) as f:
            result = json.load(f)
        if args.keep:
            os.makedirs(args.keep, exist_ok=True)
            stem = os.path.splitext(os.path.basename(scene_path))[0]
            for src, kind in ((result_path, "result"), (model_path, "model")):
                with open(src) as f, open(os.path.join(args.keep, "%s.%s.json" % (stem, kind)),
                                          "w") as g:
                    g.write(f.read())
    pairs, stiffness, from_result = read_model(model_path)
    result = result or from_result
    t = time.monotonic()
    k_fem = fem_stiffness(mesh)
    edges, k_base = van_gelder(mesh)
    g_edges = spring_matrix(mesh.nodes, edges)
    k_baseline = mss_stiffness(g_edges, k_base)
    k_model = mss_stiffness(spring_matrix(mesh.nodes, pairs), stiffness)
    evaluator = Evaluator(mesh, k_fem)
    seconds["assembly"] = time.monotonic() - t

    rep = dict(scene=mesh.name, path=scene_path, nodes=len(mesh.nodes),
               elements=len(mesh.elements),
               element_kind=("triangles, plane %s, thickness %g" % (mesh.plane, mesh.thickness)
                             if mesh.dim == 2 else "tetrahedra"),
               material="%s, E %s, nu %s" % ("/".join(mesh.material_models),
                                            "/".join("%g" % v for v in np.unique(mesh.young)),
                                            "/".join("%g" % v for v in np.unique(mesh.poisson))),
               support_sizes=[len(s) for s in mesh.supports],
               support_dofs=[int(s.free.size) for s in evaluator.supports],
               load_scale=load_scale(mesh), baseline_springs=len(edges),
               model=dict(source=given or "springfit run %s" % args.run_args,
                          springs=len(pairs), run_seconds=run_seconds),
               families={}, eigen=[], seconds=seconds)

    models = (k_model, k_baseline, g_edges, k_base)
    for fam in FAMILIES:
        rep["families"][fam] = evaluate_family(args, mesh, evaluator, fam, models, seconds)

    t = time.monotonic()
    for s, sup in enumerate(evaluator.supports):
        if sup.free.size > args.eig_max_dofs:
            rep["eigen"].append(None)
            continue
        rep["eigen"].append(dict(springfit=generalized_extremes(k_model, k_fem, sup),
                                 baseline=generalized_extremes(k_baseline, k_fem, sup)))
    seconds["eigenvalues"] = time.monotonic() - t

    if not args.no_checks:
        t = time.monotonic()
        checks = {}
        if os.path.exists(args.springfit):
            checks["reference"] = check_reference(args, mesh, scene_path, evaluator, tmp)
        if result is not None:
            named = family_named(mesh)
            reference = evaluator.fem_responses(named)
            same = mesh.linear and result.get("response") == "linear"
            for key, k_full, theirs in (
                    ("baseline", k_baseline, result.get("baseline", {}).get("rms_error")),
                    ("model", k_model, result.get("rms_error"))):
                here = evaluator.pooled(k_full, named, reference)
                checks[key] = dict(here=here, springfit=theirs, same_response=same,
                                   relative_difference=(abs(here - theirs) / theirs
                                                        if theirs else math.nan))
        rep["checks"] = checks
        seconds["checks"] = time.monotonic() - t
    if args.unnamed_supports > 0:
        rep["unnamed"] = evaluate_unnamed(args, mesh, k_fem, models, seconds)
    seconds["total"] = time.monotonic() - t0
    return rep


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", default=DEFAULT_SCENES)
    parser.add_argument("--springfit", default="build/client/springfit")
    parser.add_argument("--run-args", default="", help="further options for springfit run")
    parser.add_argument("--model", action="append", default=[],
                        help="a model JSON (springfit export) or a run -o result, one per scene "
                             "in order, instead of running springfit")
    parser.add_argument("--seed", type=int, default=20261126)
    parser.add_argument("--pushed", type=int, default=20, help="pushed nodes per support")
    parser.add_argument("--patches", type=int, default=30, help="patch loads per support")
    parser.add_argument("--train-factor", type=int, default=3,
                        help="the best fits' training draws: this many times the evaluation "
                             "draw's pushed nodes (at most every free boundary node) and patches")
    parser.add_argument("--skip-best", action="store_true", help="no best-model fits")
    parser.add_argument("--best-seconds", type=float, default=120.0,
                        help="time bound of each best-model fit")
    parser.add_argument("--best-evaluations", type=int, default=5000,
                        help="bound on the L-BFGS-B evaluations of each best-model fit")
    parser.add_argument("--eig-max-dofs", type=int, default=5000)
    parser.add_argument("--unnamed-supports", type=int, default=0,
                        help="per scene, this many supports drawn here (kinds in turn: a "
                             "third of the boundary, a random arc, two-sided), with the "
                             "families pushed, gravity and patch on them")
    parser.add_argument("--no-checks", action="store_true")
    parser.add_argument("--json", help="write every number to this file")
    parser.add_argument("--keep", help="keep springfit's result and model files here")
    args = parser.parse_args()
    if args.model and len(args.model) != len(args.scenes):
        parser.error("--model: %d given for %d scenes" % (len(args.model), len(args.scenes)))

    info = machine()
    print("# Generalisation (bench/generalization.py), seed %d" % args.seed)
    print("machine: %d CPUs (nproc), %s; python %s, numpy %s, scipy %s; tree %s; %s" % (
        info["nproc"], info["cpu"], info["python"], info["numpy"], info["scipy"],
        info["commit"] or "?", info["date"]))
    if args.model:
        print("models: " + ", ".join(args.model))
    elif os.path.exists(args.springfit):
        print("models: %s run SCENE %s (binary of %s)" % (
            args.springfit, args.run_args,
            time.strftime("%Y-%m-%d %H:%M", time.localtime(os.path.getmtime(args.springfit)))))
    print("E: relative RMS nodal error of one load over the free nodes; med / p95 over the "
          "family's loads; linear responses (FEM at its small-strain limit, springs "
          "linearised at rest)")
    reports = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, scene in enumerate(args.scenes):
            model = args.model[i] if args.model else None
            rep = evaluate_scene(args, scene, model, tmp, i)
            print_scene(rep)
            reports.append(rep)
    if args.json:
        with open(args.json, "w") as f:
            options = {k: v for k, v in vars(args).items()      # as before --unnamed-supports
                       if k != "unnamed_supports" or v}
            json.dump(jsonable(dict(machine=info, seed=args.seed, args=options,
                                    scenes=reports)), f, indent=1)


if __name__ == "__main__":
    main()
