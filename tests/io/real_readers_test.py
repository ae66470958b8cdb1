#!/usr/bin/env python3
"""springfit export read back by the readers a user opens the files with (issue 47 item 4).

A 3D box is meshed by Gmsh with node tags from 70,001 (past what 8- and 16-bit integers hold),
imported with a loads file that states units (mm, mN) and a density (kg/mm^3), run, and
exported to .vtk, .vtu, .msh, .scn and .json. Then, with no springfit code:
- VTK's own readers (vtkUnstructuredGridReader, vtkXMLUnstructuredGridReader) and the Gmsh
  library's (gmsh.open, gmsh.view.getModelData) read the models;
- every node's `node_tag` is the Gmsh tag of the source mesh's node at the same place;
- every node's `mass` is its share of the tetrahedra around it (a quarter of each volume times
  the density, computed here from the source mesh), the masses sum to density x box volume,
  and the SOFA scene's DiagonalMass holds the same masses;
- every file states its units, mass and time included, and `export` prints the total mass and
  the stable time step with theirs.

Usage: real_readers_test.py SPRINGFIT SOURCE_DIR
"""
import json
import re
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

import gmsh
import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

SF = sys.argv[1]
FIRST_TAG = 70001
DENSITY = 1.05e-6  # kg/mm^3 (1,050 kg/m^3) in mm and mN
SIDE = 10.0  # mm
UNITS = "units: length mm, force mN, stiffness mN/mm, mass kg, time s"

failures = []


def check(ok, what):
    if not ok:
        failures.append(what)
        print("FAIL:", what)


def run(*args, accept=(0,)):
    p = subprocess.run([SF, *args], capture_output=True, text=True)
    if p.returncode not in accept:
        sys.exit(f"springfit {' '.join(args)} exited {p.returncode}: {p.stderr}")
    return p


def close(a, b, rel=1e-12):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a.shape == b.shape and np.all(np.abs(a - b) <= rel * np.maximum(np.abs(b).max(), 1e-300))


def source_mesh(path):
    """The source mesh by Gmsh's library: {tag: xyz} and each tag's lumped mass."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.open(path)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    xyz = dict(zip((int(t) for t in tags), coords.reshape(-1, 3)))
    mass = dict.fromkeys(xyz, 0.0)
    types, _, nodes = gmsh.model.mesh.getElements(3)
    for etype, enodes in zip(types, nodes):
        if etype != 4:  # 4-node tetrahedra only
            continue
        for tet in enodes.reshape(-1, 4):
            a, b, c, d = (xyz[int(t)] for t in tet)
            share = DENSITY * abs(np.dot(b - a, np.cross(c - a, d - a))) / 6.0 / 4.0
            for t in tet:
                mass[int(t)] += share
    gmsh.finalize()
    return xyz, {t: m for t, m in mass.items() if m > 0.0}


def check_nodes(where, points, node_tag, mass, src_xyz, src_mass):
    check(len(points) == len(src_mass), f"{where}: {len(points)} points, the mesh has {len(src_mass)} nodes")
    tags = [int(round(t)) for t in node_tag]
    check(all(float(t) == float(v) for t, v in zip(tags, node_tag)), f"{where}: node_tag not whole numbers")
    check(sorted(tags) == sorted(src_mass), f"{where}: node tags {tags[:4]} are not the mesh's {sorted(src_mass)[:4]}")
    check(min(tags) >= FIRST_TAG, f"{where}: a node tag {min(tags)} below the mesh's first {FIRST_TAG}")
    for i, t in enumerate(tags):
        if t not in src_xyz:
            continue
        if not close(points[i], src_xyz[t]):
            check(False, f"{where}: point {i} tagged {t} at {points[i]}, the mesh's node {t} at {src_xyz[t]}")
            break
    expected = [src_mass.get(t, float("nan")) for t in tags]
    check(close(mass, expected, 1e-9), f"{where}: node masses differ from the tetrahedra's shares")
    check(abs(sum(mass) - DENSITY * SIDE ** 3) <= 1e-9 * DENSITY * SIDE ** 3,
          f"{where}: total mass {sum(mass)}, density x volume {DENSITY * SIDE ** 3}")


def point_array(data, name, where):
    array = data.GetPointData().GetArray(name)
    if array is None:
        check(False, f"{where}: no point data '{name}'")
        return None
    return array


def read_vtk(reader_class, path, where, src_xyz, src_mass):
    reader = reader_class()
    reader.SetFileName(path)
    if hasattr(reader, "ReadAllScalarsOn"):  # legacy: every SCALARS block, as ParaView reads it
        reader.ReadAllScalarsOn()
        reader.ReadAllVectorsOn()
    reader.Update()
    grid = reader.GetOutput()
    points = vtk_to_numpy(grid.GetPoints().GetData())
    tag, mass = point_array(grid, "node_tag", where), point_array(grid, "mass", where)
    if tag is None or mass is None:
        return None
    # A tag past 65,535 needs an integer type wider than 16 bits, or a double.
    check(tag.GetDataType() in (vtk.VTK_INT, vtk.VTK_UNSIGNED_INT, vtk.VTK_LONG, vtk.VTK_LONG_LONG,
                                vtk.VTK_ID_TYPE, vtk.VTK_TYPE_INT64, vtk.VTK_DOUBLE),
          f"{where}: node_tag is a {tag.GetDataTypeAsString()}")
    check_nodes(where, points, vtk_to_numpy(tag), vtk_to_numpy(mass), src_xyz, src_mass)
    return reader


def read_msh(path, src_xyz, src_mass):
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.open(path)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    order = np.argsort(tags)
    points = coords.reshape(-1, 3)[order]
    views = {gmsh.option.getString(f"View[{gmsh.view.getIndex(v)}].Name"): v for v in gmsh.view.getTags()}
    values = {}
    for name in ("node_tag", "mass"):
        if name not in views:
            check(False, f".msh: no view '{name}' (views: {sorted(views)})")
            gmsh.finalize()
            return
        kind, vtags, data, _, _ = gmsh.view.getModelData(views[name], 0)
        check(kind == "NodeData", f".msh: view {name} is {kind}")
        by_tag = dict(zip((int(t) for t in vtags), (d[0] for d in data)))
        values[name] = [by_tag[int(t)] for t in np.asarray(tags)[order]]
    gmsh.finalize()
    check_nodes(".msh", points, values["node_tag"], values["mass"], src_xyz, src_mass)


with tempfile.TemporaryDirectory() as work:
    with open(f"{work}/box.geo", "w") as f:
        f.write(f"""SetFactory("OpenCASCADE");
Box(1) = {{0, 0, 0, {SIDE}, {SIDE}, {SIDE}}};
Physical Surface("left") = {{1}};
Physical Surface("right") = {{2}};
Physical Volume("tissue") = {{1}};
Mesh.CharacteristicLengthMax = 4;
""")
    with open(f"{work}/loads.json", "w") as f:
        json.dump({
            "units": {"length": "mm", "force": "mN", "modulus": "kPa"},
            "reference": {"materials": {"tissue": {"model": "linear", "young": 10, "poisson": 0.45,
                                                   "density": DENSITY}}},
            "load_cases": [
                {"name": "stretch", "fixed": "left", "tractions": [{"on": "right", "total": [1, 0, 0]}]},
                {"name": "shear", "fixed": "left", "tractions": [{"on": "right", "total": [0, 0.3, 0]}]},
                {"name": "lift", "fixed": "left", "tractions": [{"on": "right", "total": [0, 0, 0.3]}]},
            ]}, f)
    p = subprocess.run(["gmsh", f"{work}/box.geo", "-3", "-setnumber", "Mesh.FirstNodeTag", str(FIRST_TAG),
                        "-o", f"{work}/box.msh"], capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"gmsh: {p.stdout[-400:]}")
    src_xyz, src_mass = source_mesh(f"{work}/box.msh")
    run("run", f"{work}/box.msh", "--loads", f"{work}/loads.json", "-q",
        "-o", f"{work}/result.json", accept=(0, 12))  # 12: a doubtful verdict, a model all the same

    printed = {}
    for ext in ("vtk", "vtu", "msh", "scn", "json"):
        printed[ext] = run("export", f"{work}/result.json", "-o", f"{work}/model.{ext}").stdout
    total = DENSITY * SIDE ** 3
    for ext, out in printed.items():
        check(f"total mass {total:.4g} kg" in out, f"export .{ext} prints no total mass in kg: {out}")
        check(re.search(r"stable explicit time step at most [0-9.e+-]+ s\b", out),
              f"export .{ext}: no stable time step in seconds: {out}")

    legacy = read_vtk(vtk.vtkUnstructuredGridReader, f"{work}/model.vtk", ".vtk", src_xyz, src_mass)
    if legacy is not None:
        check(UNITS in legacy.GetHeader(), f".vtk: the header states no units: {legacy.GetHeader()}")
    read_vtk(vtk.vtkXMLUnstructuredGridReader, f"{work}/model.vtu", ".vtu", src_xyz, src_mass)
    check(UNITS in open(f"{work}/model.vtu").read(), ".vtu: its description states no units")
    read_msh(f"{work}/model.msh", src_xyz, src_mass)
    check(UNITS in open(f"{work}/model.msh").read(), ".msh: its $Comments state no units")

    # The SOFA scene: DiagonalMass in the scene's node order, the same masses.
    text = open(f"{work}/model.scn").read()
    check(UNITS in text, ".scn: its comment states no units")
    mass = np.array([float(v) for v in ET.fromstring(text).find(".//DiagonalMass").get("vertexMass").split()])
    model = json.load(open(f"{work}/model.json"))
    tags = model.get("node_tags") or json.load(open(f"{work}/result.json"))["scene_definition"]["node_tags"]
    check(close(mass, [src_mass[t] for t in tags], 1e-9), ".scn: DiagonalMass differs from the tetrahedra's shares")
    # The JSON model: units in full, the facts' total mass.
    check(model["units"] == {"length": "mm", "force": "mN", "stiffness": "mN/mm", "modulus": "kPa",
                             "mass": "kg", "time": "s"}, f".json: units {model['units']}")
    check(abs(model["facts"]["total_mass"] - total) <= 1e-9 * total, f".json: total mass {model['facts']['total_mass']}")

print("real_readers: " + ("all checks passed" if not failures else f"{len(failures)} failed"))
sys.exit(1 if failures else 0)
