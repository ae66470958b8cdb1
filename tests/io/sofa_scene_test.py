#!/usr/bin/env python3
"""springfit export -o model.scn: the SOFA scene of every release, read as SOFA reads it.

For each release springfit writes (v23.06 to v26.06) and a 2D and a 3D model, the scene is
parsed with an XML parser and interpreted by SOFA's documented semantics, independently of
springfit's writer:
- the components that release has (from SOFA's sources: StiffSpringForceField up to v24.06,
  SpringForceField from v24.12; FixedConstraint up to v23.12, FixedProjectiveConstraint from
  v24.06; a NewtonRaphsonSolver beside StaticSolver from v25.06), each with its module loaded
  by a RequiredPlugin;
- the MechanicalObject's positions, the spring data "index1 index2 stiffness damping
  rest_length" per spring, the fixed and partially fixed (z) indices, the ConstantForceField's
  one force per index;
then this script's own static solver (Newton on the springs' forces with SOFA's spring law,
f = k (l - L0) along the current direction, as SOFA's StaticSolver) finds the equilibrium,
which must equal springfit's prediction to 1e-6: the model_displacement springfit's JSON export
carries and the monitored nodes the scene states (`springfit-expected`), both computed by
springfit's engine with nonlinear springs whatever response the fit was judged with. Masses
(UniformMass / DiagonalMass summing to the lumped total), the dynamic variant and the refusals
are checked too.

Usage: sofa_scene_test.py SPRINGFIT SOURCE_DIR
"""
import json
import os
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

import numpy as np

SF, SRC = sys.argv[1], sys.argv[2]
RELEASES = ["v23.06", "v23.12", "v24.06", "v24.12", "v25.06", "v25.12", "v26.06"]
# The module each component lives in (SOFA's CMake projects, the same in every release here).
MODULE = {
    "MechanicalObject": "Sofa.Component.StateContainer",
    "EdgeSetTopologyContainer": "Sofa.Component.Topology.Container.Dynamic",
    "SpringForceField": "Sofa.Component.SolidMechanics.Spring",
    "StiffSpringForceField": "Sofa.Component.SolidMechanics.Spring",
    "FixedConstraint": "Sofa.Component.Constraint.Projective",
    "FixedProjectiveConstraint": "Sofa.Component.Constraint.Projective",
    "PartialFixedConstraint": "Sofa.Component.Constraint.Projective",
    "PartialFixedProjectiveConstraint": "Sofa.Component.Constraint.Projective",
    "ConstantForceField": "Sofa.Component.MechanicalLoad",
    "UniformMass": "Sofa.Component.Mass",
    "DiagonalMass": "Sofa.Component.Mass",
    "StaticSolver": "Sofa.Component.ODESolver.Backward",
    "NewtonRaphsonSolver": "Sofa.Component.ODESolver.Backward",
    "EulerImplicitSolver": "Sofa.Component.ODESolver.Backward",
    "SparseLDLSolver": "Sofa.Component.LinearSolver.Direct",
}
FRAMEWORK = {"Node", "RequiredPlugin", "DefaultAnimationLoop"}

failures = []


def check(ok, what):
    if not ok:
        failures.append(what)
        print("FAIL:", what)


def run(*args, expect=0):
    p = subprocess.run([SF, *args], capture_output=True, text=True)
    if p.returncode != expect:
        failures.append(f"{' '.join(args)}: exit {p.returncode}, expected {expect}: {p.stderr[-400:]}")
        print("FAIL:", failures[-1])
    return p


def expected_components(release):
    i = RELEASES.index(release)
    return {
        "springs": "SpringForceField" if i >= RELEASES.index("v24.12") else "StiffSpringForceField",
        "fixed": "FixedProjectiveConstraint" if i >= RELEASES.index("v24.06") else "FixedConstraint",
        "partial": ("PartialFixedProjectiveConstraint" if i >= RELEASES.index("v24.06")
                    else "PartialFixedConstraint"),
        "newton": i >= RELEASES.index("v25.06"),
    }


def floats(text):
    return np.array([float(x) for x in text.split()])


def read_scene(path, release, dim):
    """The scene as SOFA would build it: positions, springs, held dofs, forces, masses."""
    root = ET.parse(path).getroot()
    tags = [e.tag for e in root.iter()]
    plugins = {e.get("name") for e in root.iter("RequiredPlugin")}
    for tag in set(tags) - FRAMEWORK:
        check(tag in MODULE, f"{path}: component {tag} unknown to this test")
        check(MODULE.get(tag) in plugins, f"{path}: {tag} without RequiredPlugin {MODULE.get(tag)}")
    want = expected_components(release)
    for other in {"SpringForceField", "StiffSpringForceField"} - {want["springs"]}:
        check(other not in tags, f"{release}: {other} where the release needs {want['springs']}")
    check(want["springs"] in tags, f"{release}: no {want['springs']}")
    check(("NewtonRaphsonSolver" in tags) == want["newton"] or "EulerImplicitSolver" in tags,
          f"{release}: NewtonRaphsonSolver present {('NewtonRaphsonSolver' in tags)}")
    gravity = floats(root.get("gravity"))
    check(len(gravity) == 3, f"{path}: gravity is a 3-vector, got {root.get('gravity')}")
    node = root.find("Node")
    mo = node.find("MechanicalObject")
    check(mo.get("template") == "Vec3d", f"{path}: MechanicalObject template {mo.get('template')}")
    x0 = floats(mo.get("position")).reshape(-1, 3)
    rest = floats(mo.get("rest_position")).reshape(-1, 3)
    n = len(x0)
    topo = floats(node.find("EdgeSetTopologyContainer").get("position")).reshape(-1, 3)
    check(len(topo) == n, f"{path}: the topology has {len(topo)} points for {n} nodes")
    field = node.find(want["springs"])
    if field is None:
        return dict(root=root, node=node, tags=tags, x0=x0, rest=rest, springs=[], fixed=np.ones((n, 3), bool),
                    force=np.zeros((n, 3)), mass=None)
    s = floats(field.get("spring")).reshape(-1, 5)
    springs = [(int(a), int(b), k, kd, l0) for a, b, k, kd, l0 in s]
    fixed = np.zeros((n, 3), bool)
    for f in node.findall(want["fixed"]):
        fixed[[int(i) for i in f.get("indices").split()], :] = True
    for f in node.findall(want["partial"]):
        check(f.get("fixAll") == "1", f"{path}: partial constraint not on every node")
        fixed[:, floats(f.get("fixedDirections")) == 1] = True
    for old in ({"FixedConstraint", "FixedProjectiveConstraint"} - {want["fixed"]}):
        check(old not in tags, f"{release}: {old} where the release needs {want['fixed']}")
    if dim == 2:
        check(fixed[:, 2].all() and np.all(x0[:, 2] == 0), f"{path}: a 2D model not held in z = 0")
    force = np.zeros((n, 3))
    cff = node.find("ConstantForceField")
    if cff is not None:
        idx = [int(i) for i in cff.get("indices").split()]
        fs = floats(cff.get("forces")).reshape(-1, 3)
        check(len(fs) == len(idx), f"{path}: one force per index")
        for i, f in zip(idx, fs):
            force[i] += f
    mass = None
    if node.find("UniformMass") is not None:
        mass = np.full(n, float(node.find("UniformMass").get("vertexMass")))
    if node.find("DiagonalMass") is not None:
        mass = floats(node.find("DiagonalMass").get("vertexMass"))
        check(len(mass) == n, f"{path}: DiagonalMass has {len(mass)} masses for {n} nodes")
    return dict(root=root, node=node, tags=tags, x0=x0, rest=rest, springs=springs, fixed=fixed,
                force=force, mass=mass)


def spring_forces(x, springs, linear, rest):
    """Internal forces and stiffness matrix. linear: springs keep their rest direction."""
    n = len(x)
    f = np.zeros((n, 3))
    K = np.zeros((3 * n, 3 * n))
    for a, b, k, _, l0 in springs:
        if linear:
            d0 = rest[b] - rest[a]
            u = d0 / np.linalg.norm(d0)
            stretch = u @ ((x[b] - rest[b]) - (x[a] - rest[a]))
            fa = k * stretch * u
            Kab = k * np.outer(u, u)
        else:
            d = x[b] - x[a]
            l = np.linalg.norm(d)
            u = d / l
            fa = k * (l - l0) * u
            Kab = k * np.outer(u, u) + k * (l - l0) / l * (np.eye(3) - np.outer(u, u))
        f[a] += fa
        f[b] -= fa
        for i, j, sign in ((a, a, 1), (b, b, 1), (a, b, -1), (b, a, -1)):
            K[3 * i:3 * i + 3, 3 * j:3 * j + 3] += sign * Kab
    return f, K


def equilibrium(scene, linear):
    """Newton from the scene's start, held dofs fixed, as SOFA's static solver iterates."""
    x = scene["x0"].copy()
    free = ~scene["fixed"].reshape(-1)
    scale = max(np.abs(scene["force"]).max(), 1e-300)
    for _ in range(60):
        f, K = spring_forces(x, scene["springs"], linear, scene["rest"])
        r = (scene["force"] + f).reshape(-1)
        if np.abs(r[free]).max() <= 1e-11 * scale:
            return x
        dx = np.zeros(3 * len(x))
        dx[free] = np.linalg.solve(K[np.ix_(free, free)], r[free])
        x = x + dx.reshape(-1, 3)
    return None


def as3(rows, dim):
    a = np.array(rows, float)
    return np.hstack([a, np.zeros((len(a), 3 - dim))]) if dim == 2 else a


def check_model(label, result, dim, case_index, extra=()):
    tmp = tempfile.mkdtemp()
    run("export", result, "-o", f"{tmp}/model.json", *extra)
    model = json.load(open(f"{tmp}/model.json"))
    case = model["load_cases"][case_index]
    own = as3(case["model_displacement"], dim)
    for release in RELEASES:
        path = f"{tmp}/{release}.scn"
        run("export", result, "-o", path, "--sofa-version", release, "--case", case["name"], *extra)
        scene = read_scene(path, release, dim)
        check(np.allclose(scene["rest"], as3(model["nodes"], dim), rtol=0, atol=0),
              f"{label} {release}: rest positions")
        check(len(scene["springs"]) == len(model["springs"]), f"{label} {release}: spring count")
        for (a, b, k, kd, l0), s in zip(scene["springs"], model["springs"]):
            if (a, b) != tuple(s["nodes"]) or k != s["stiffness"] or l0 != s["rest_length"] or kd != 0:
                check(False, f"{label} {release}: spring {s} read as {(a, b, k, kd, l0)}")
                break
        held = sorted(np.flatnonzero(scene["fixed"][:, :dim].all(axis=1)))
        check(held == case["held"], f"{label} {release}: held nodes {held[:8]} vs {case['held'][:8]}")
        # What SOFA computes: its springs turn and stretch (the nonlinear law), whatever response
        # the fit was judged with; springfit's prediction (the model's model_displacement and
        # the scene's own springfit-expected lines) is that equilibrium, to 1e-6.
        x = equilibrium(scene, False)
        check(x is not None, f"{label} {release}: no equilibrium")
        if x is None:
            continue
        u = x - scene["rest"]
        size = np.abs(own).max()
        err = np.abs(u - own).max() / size
        check(err <= 1e-6, f"{label} {release}: SOFA's equilibrium differs from springfit's "
                           f"prediction by {err:.2e} of the largest displacement")
        expected = [line.split()[1:] for line in open(path).read().splitlines()
                    if line.strip().startswith("springfit-expected ")]
        check(len(expected) == min(5, len(u)), f"{label} {release}: {len(expected)} monitored nodes")
        for node, *ux in expected:
            ux = np.array(ux, float)
            gap = np.abs(u[int(node)] - ux).max() / max(np.abs(ux).max(), 1e-300)
            check(gap <= 1e-6, f"{label} {release}: node {node} at {u[int(node)]}, the scene "
                               f"states {ux} ({gap:.2e})")
        if expected:
            top = np.linalg.norm(u, axis=1).max()
            check(abs(np.linalg.norm(np.array(expected[0][1:], float)) - top) <= 1e-6 * top,
                  f"{label} {release}: the first monitored node is not the one that moves most")
    print(f"{label}: {len(RELEASES)} releases, case '{case['name']}', "
          f"judged with the {model['response']} response, {len(model['springs'])} springs")
    return tmp, model


with tempfile.TemporaryDirectory() as work:
    plate = f"{work}/plate.json"
    run("example", "fem-plate-5x5", "-o", f"{work}/plate-scene.json")
    summary = run("run", f"{work}/plate-scene.json", "-o", plate).stdout
    grid = f"{work}/grid.json"
    run("run", f"{SRC}/examples/grid3d-4x4x4.json", "--strategy", "direct", "-o", grid)
    kidney = f"{work}/kidney.json"
    run("run", f"{SRC}/examples/kidney-2d.json", "--strategy", "direct", "-o", kidney)

    _, plate_model = check_model("2D FEM plate (linear response)", plate, 2, 1)
    # The run's summary states the same stiffness facts as the export.
    f = plate_model["facts"]
    line = next((l for l in summary.splitlines() if l.startswith("stiffness:")), "")
    check(f"{f['min_stiffness']:.4g} to {f['max_stiffness']:.4g}, median {f['median_stiffness']:.4g}" in line
          and f"; {f['dead_springs']} dead" in line, f"the run's stiffness line: {line!r} vs {f}")
    check_model("3D grid (nonlinear)", grid, 3, 4)
    check_model("2D kidney MSS (nonlinear)", kidney, 2, 0)

    # Masses: lumped from the plate's mesh (32 triangles of the 4 x 4 plate, thickness 0.1
    # as the example states) into a DiagonalMass; --node-mass a UniformMass; the dynamic scene.
    scene_json = json.load(open(f"{work}/plate-scene.json"))
    thickness = scene_json["reference"].get("thickness", 1.0)
    p = run("export", plate, "-o", f"{work}/lumped.scn", "--density", "2", "--dynamic",
            "--rayleigh-stiffness", "0.2", "--rayleigh-mass", "0.3", "--gravity", "0,-9.81")
    s = read_scene(f"{work}/lumped.scn", "v26.06", 2)
    nodes = np.array(scene_json["nodes"], float)
    area = 0.0
    for e in scene_json["reference"]["elements"]:
        a, b, c = nodes[e]
        area += abs(np.cross(b - a, c - a)) / 2
    check(s["mass"] is not None and abs(s["mass"].sum() - 2 * area * thickness) <= 1e-12 * area,
          f"lumped masses sum to {None if s['mass'] is None else s['mass'].sum()}, "
          f"expected {2 * area * thickness}")
    check("DiagonalMass" in s["tags"] and "EulerImplicitSolver" in s["tags"]
          and "StaticSolver" not in s["tags"], f"dynamic scene components {set(s['tags'])}")
    ode = s["node"].find("EulerImplicitSolver")
    check(ode.get("rayleighStiffness") == "0.2" and ode.get("rayleighMass") == "0.3",
          "Rayleigh damping as given")
    check(s["root"].get("gravity") == "0 -9.81 0", f"gravity {s['root'].get('gravity')}")
    # springfit's prediction has no gravity: such a scene states none rather than a wrong one.
    text = open(f"{work}/lumped.scn").read()
    check("springfit-expected" not in text and "this scene adds gravity" in text,
          "a gravity scene states a prediction without gravity")
    check("total mass" in p.stdout and "stable explicit time step at most" in p.stdout,
          f"the export's facts: {p.stdout}")
    # What the result says of the model, in the run's words: its verdict line, the certificate's
    # eigenvalues, and the verdict at the end of the description every format carries.
    verdict = next((l for l in summary.splitlines() if l.startswith("verdict:")), "")
    headline = verdict[len("verdict:"):].strip()
    result = json.load(open(plate))
    g = result["generalization"]
    check(headline and f"verdict {headline}; generalised eigenvalues of (K_model, K_ref) on the "
          f"user's supports in [{g['lambda_min']:.3g}, {g['lambda_max']:.3g}]" in p.stdout,
          f"the export's verdict line: {p.stdout!r} vs the run's {verdict!r}")
    check(plate_model["description"].endswith("; " + headline),
          f"the model's description {plate_model['description']!r} ends with {headline!r}")
    # The material's density in the scene: the same masses without --density.
    with_density = dict(scene_json)
    with_density["reference"] = dict(scene_json["reference"], material=dict(scene_json["reference"]["material"], density=2))
    json.dump(with_density, open(f"{work}/dense-scene.json", "w"))
    run("run", f"{work}/dense-scene.json", "-o", f"{work}/dense.json")
    p = run("export", f"{work}/dense.json", "-o", f"{work}/dense.scn")
    s2 = read_scene(f"{work}/dense.scn", "v26.06", 2)
    check(s2["mass"] is not None and np.allclose(s2["mass"], s["mass"], rtol=1e-15),
          "the material's density gives the masses --density gives")
    check("the materials' density lumped on the 32 triangles" in p.stdout, p.stdout)
    with_density["reference"]["material"]["density"] = -1
    json.dump(with_density, open(f"{work}/bad-density.json", "w"))
    p = run("check", f"{work}/bad-density.json", expect=2)
    check("reference.material.density" in p.stderr, p.stderr)
    run("export", plate, "-o", f"{work}/uniform.scn", "--node-mass", "0.5")
    s = read_scene(f"{work}/uniform.scn", "v26.06", 2)
    check("UniformMass" in s["tags"] and np.all(s["mass"] == 0.5), "UniformMass of --node-mass")

    # Dead springs: below --dead-fraction of the median, flagged, or left out with --drop-dead.
    # The median is the result's springs' (the one run and result print), whatever the export
    # adds between held nodes.
    run("export", plate, "-o", f"{work}/flagged.json", "--dead-fraction", "0.2")
    flagged = json.load(open(f"{work}/flagged.json"))
    fitted = sorted(json.load(open(plate))["stiffness"])
    n = len(fitted)
    median = fitted[n // 2] if n % 2 else 0.5 * (fitted[n // 2 - 1] + fitted[n // 2])
    check(flagged["facts"]["fitted_median_stiffness"] == median
          and abs(flagged["facts"]["dead_threshold"] - 0.2 * median) <= 1e-15 * median,
          f"the dead threshold is of the result's median {median}: {flagged['facts']}")
    dead = [s for s in flagged["springs"] if s["dead"]]
    check(dead and all(s["stiffness"] < 0.2 * median for s in dead)
          and all(s["stiffness"] >= 0.2 * median for s in flagged["springs"] if not s["dead"])
          and flagged["facts"]["dead_springs"] == len(dead), "dead springs flagged")
    p = run("export", plate, "-o", f"{work}/dropped.scn", "--dead-fraction", "0.2", "--drop-dead")
    s = read_scene(f"{work}/dropped.scn", "v26.06", 2)
    check(len(s["springs"]) == len(flagged["springs"]) - len(dead), "--drop-dead leaves them out")
    check(f"{len(dead)} dead springs (below {0.2 * median:.4g}: 0.2 x the fitted springs' median "
          f"{median:.4g}), left out" in p.stdout, p.stdout)
    # The springs between held nodes that the export adds (the grid's 3, at the training
    # stiffness 1) are not the fit's: the dead threshold is the result's median's fraction.
    edited = json.load(open(grid))
    edited["stiffness"] = [1.0 + i for i in range(len(edited["springs"]))]
    json.dump(edited, open(f"{work}/grid-edited.json", "w"))
    p = run("export", f"{work}/grid-edited.json", "-o", f"{work}/grid-edited-model.json",
            "--dead-fraction", "0.5")
    facts = json.load(open(f"{work}/grid-edited-model.json"))["facts"]
    n = len(edited["stiffness"])
    want = 1.0 + n // 2 if n % 2 else 0.5 * (2.0 + n // 2 - 1 + n // 2)
    held = len(edited["unidentifiable"])
    check(held > 0 and facts["fitted_median_stiffness"] == want
          and facts["dead_threshold"] == 0.5 * want
          and facts["dead_springs"] == held + sum(1 for k in edited["stiffness"] if k < 0.5 * want),
          f"the dead threshold of a model with {held} springs between held nodes: {facts}, "
          f"the result's median {want}")
    check(f"over the {n + held} springs in the file" in p.stdout, p.stdout)
    # The facts describe the springs the file holds, not the ones left out.
    run("export", plate, "-o", f"{work}/dropped.json", "--dead-fraction", "0.2", "--drop-dead")
    dropped = json.load(open(f"{work}/dropped.json"))
    kept = sorted(s["stiffness"] for s in dropped["springs"])
    check(dropped["facts"]["min_stiffness"] == kept[0] and dropped["facts"]["max_stiffness"] == kept[-1]
          and dropped["facts"]["dead_springs"] == len(dead) and dropped["facts"]["dead_dropped"],
          f"--drop-dead's facts: {dropped['facts']}, kept {kept[0]} to {kept[-1]}")

    # The stable explicit time step: safe (at most 2 / omega_max of the model linearised at
    # rest with its masses), and not far below it.
    run("export", grid, "-o", f"{work}/grid-mass.json", "--node-mass", "0.01")
    gm = json.load(open(f"{work}/grid-mass.json"))
    x = np.array(gm["nodes"], float)
    springs = [(s["nodes"][0], s["nodes"][1], s["stiffness"], 0, s["rest_length"]) for s in gm["springs"]]
    _, K = spring_forces(x, springs, True, x)
    m = np.repeat(np.array(gm["masses"]), 3)
    omega2 = np.linalg.eigvalsh(K / np.sqrt(np.outer(m, m))).max()
    exact = 2 / np.sqrt(omega2)
    dt = gm["facts"]["stable_time_step"]
    check(dt is not None and 0.35 * exact <= dt <= exact, f"stable step {dt} against 2/omega_max {exact}")
    print(f"stable explicit step: {dt:.4g}, exact limit {exact:.4g}")

    # Refusals: exit 2, the option named.
    for args, message in (
            (["--sofa-version", "v22.12"], "unknown SOFA release 'v22.12' (known: v23.06"),
            (["--case", "nope"], "no load case 'nope' (the scene's: "),
            (["--dynamic"], "--dynamic: needs the nodes' masses"),
            (["--density", "1", "--node-mass", "1"], "give --density (lumped on the mesh) or --node-mass"),
    ):
        p = run("export", plate, "-o", f"{work}/bad.scn", *args, expect=2)
        check(message in p.stderr, f"{args}: {p.stderr}")
        check(not os.path.exists(f"{work}/bad.scn"), f"{args}: a file was written")
    # A release as users write it, without SOFA's "v": the same scene as with it.
    run("export", plate, "-o", f"{work}/bare.scn", "--sofa-version", "24.06")
    run("export", plate, "-o", f"{work}/named.scn", "--sofa-version", "v24.06")
    check(open(f"{work}/bare.scn").read() == open(f"{work}/named.scn").read(),
          "--sofa-version 24.06 and v24.06 differ")
    p = run("export", plate, "-o", f"{work}/bad.vtu", "--sofa-version", "v24.06", expect=2)
    check("--sofa-version: applies to a SOFA scene (.scn)" in p.stderr, p.stderr)
    p = run("export", grid, "-o", f"{work}/bad.scn", "--density", "1", expect=2)
    check("no FEM mesh to lump a density on" in p.stderr, p.stderr)

print("sofa_scene: " + ("all checks passed" if not failures else f"{len(failures)} failed"))
sys.exit(1 if failures else 0)
