#!/usr/bin/env bash
# Decks as Gmsh writes them (gmsh -2/-3 ... -o mesh.inp): lower-dimensional elements beside the
# mesh left out with a note, physical groups (element sets, or node sets with
# Mesh.SaveGroupsOfNodes) as node sets and regions, no *SOLID SECTION and no *STEP filled from
# --loads, inverted elements and CPS3 named in notes. The pipeline example's deck gives the same
# scene as its .msh, and the same equilibria.
# Usage: gmsh_deck_test.sh SPRINGFIT SOURCE_DIR
set -u
sf=$1
src=$2
source "$(dirname "$0")/../checks.sh"
command -v gmsh >/dev/null || { echo "FAIL: gmsh is missing: run scripts/install-deps.sh"; exit 1; }
loads="$src/examples/pipeline/inclusion-loads.json"

gmsh -2 "$src/examples/pipeline/inclusion.geo" -o "$tmp/inclusion.msh" >/dev/null 2>&1 || fail "gmsh .msh"
gmsh -2 "$src/examples/pipeline/inclusion.geo" -o "$tmp/inclusion.inp" >/dev/null 2>&1 || fail "gmsh .inp"
gmsh -2 "$src/examples/pipeline/inclusion.geo" -setnumber Mesh.SaveGroupsOfNodes 1 \
  -o "$tmp/inclusion-nsets.inp" >/dev/null 2>&1 || fail "gmsh .inp with node sets"
grep -q "type=T3D2" "$tmp/inclusion.inp" || fail "gmsh no longer writes the curves as T3D2 (the case this tests)"

expect_exit 0 "import the .msh" "$sf" import "$tmp/inclusion.msh" --loads "$loads" -o "$tmp/msh.json"
expect_exit 0 "import the Gmsh deck" "$sf" import "$tmp/inclusion.inp" --loads "$loads" -o "$tmp/inp.json"
grep -q "note: .*inclusion.inp: 48 T3D2 element(s) beside the 380 triangles left out" "$tmp/err" \
  || fail "the T3D2 lines are not named: $(cat "$tmp/err")"
grep -q "note: .*CPS3 read as springfit's plane-stress triangle .* CPE3 with the plane-stress constants" "$tmp/err" \
  || fail "no CPS3 note: $(cat "$tmp/err")"
expect_exit 0 "import the Gmsh deck with node sets" "$sf" import "$tmp/inclusion-nsets.inp" --loads "$loads" -o "$tmp/nsets.json"
# The three scenes are one: nodes, elements, node sets, the regions' materials, by coordinates
# (the readers number nodes in their own orders).
python3 - "$tmp/msh.json" "$tmp/inp.json" "$tmp/nsets.json" <<'PY' || fail "the Gmsh deck is not the .msh's scene"
import json, sys
def canon(path):
    s = json.load(open(path))
    x = [tuple(round(c, 9) for c in p) for p in s["nodes"]]
    r = s["reference"]
    mats = r["materials"]
    elems = sorted((tuple(sorted(x[i] for i in e)), json.dumps(mats[m], sort_keys=True))
                   for e, m in zip(r["elements"], r["element_materials"]))
    sets = {k: sorted(x[i] for i in v) for k, v in s["node_sets"].items()}
    return sorted(x), elems, sets, len(s["load_cases"]), r["plane"]
a, b, c = (canon(p) for p in sys.argv[1:4])
assert a[0] == b[0] == c[0], "nodes"
assert a[1] == b[1] == c[1], "elements and their materials"
assert set(a[2]) == set(b[2]) == set(c[2]) == {"left", "right", "top", "bottom", "tissue", "inclusion"}, (set(a[2]), set(b[2]), set(c[2]))
assert a[2] == b[2] == c[2], "node sets"
assert a[3:] == b[3:] == c[3:] == (6, "stress")
PY
# The same equilibria (largest displacement per case) from the deck as from the mesh.
expect_exit 0 "reference of the .msh" "$sf" reference "$tmp/msh.json" --json
cp "$tmp/out" "$tmp/msh-ref.json"
expect_exit 0 "reference of the deck" "$sf" reference "$tmp/inclusion.inp" --loads "$loads" --json
python3 - "$tmp/msh-ref.json" "$tmp/out" "$tmp/msh.json" "$tmp/inp.json" <<'PY' || fail "the deck's equilibria differ from the mesh's"
import json, sys
a, b, sa, sb = (json.load(open(p)) for p in sys.argv[1:5])
a["nodes"], b["nodes"] = sa["nodes"], sb["nodes"]
def by_rest(ref):  # per case: rest position -> deformed position
    rest = [tuple(round(c, 9) for c in p) for p in ref["nodes"]]
    return [dict(zip(rest, conf)) for conf in ref["reference"]["positions"]]
A, B = by_rest(a), by_rest(b)
assert len(A) == len(B) == 6
for ca, cb in zip(A, B):
    assert ca.keys() == cb.keys()
    scale = max(abs(q - r) for x, p in ca.items() for q, r in zip(p, x))  # largest displacement
    worst = max(abs(p - q) for x in ca for p, q in zip(ca[x], cb[x]))
    assert worst <= 1e-9 * scale, (worst, scale)
PY

# The input's own node numbers travel: the .msh's tags and the deck's ids in the scene, and
# into the exported model (point data node_tag) for a user who maps results back.
expect_exit 0 "run the deck" "$sf" run "$tmp/inp.json" --probes none -q -o "$tmp/inp-result.json"
expect_exit 0 "export the deck's model" "$sf" export "$tmp/inp-result.json" -o "$tmp/inp-model.vtu"
"$debian_python" - "$tmp/msh.json" "$tmp/inp.json" "$tmp/inclusion.msh" "$tmp/inclusion.inp" "$tmp/inp-model.vtu" <<'PY' || fail "node tags"
import sys, meshio
import json
msh, inp = (json.load(open(p)) for p in sys.argv[1:3])
m = meshio.read(sys.argv[3])
# Gmsh's tags, in the order springfit numbers the nodes: the tag's point is the scene's node.
tags = msh["node_tags"]
assert len(tags) == len(msh["nodes"]) and len(set(tags)) == len(tags)
ids = {}
for line in open(sys.argv[4]).read().split("*ELEMENT")[0].split("\n")[3:]:
    f = [x.strip() for x in line.split(",")]
    if len(f) == 4:
        ids[int(f[0])] = (float(f[1]), float(f[2]))
for tag, x in zip(inp["node_tags"], inp["nodes"]):
    assert ids[tag] == tuple(x), (tag, ids[tag], x)
v = meshio.read(sys.argv[5])
assert [int(t) for t in v.point_data["node_tag"]] == inp["node_tags"]
PY
# Tags past a byte's range travel too, in both VTK formats (a .vtu once wrote them as UInt8:
# node 1000's tag read 232).
python3 -c "import json,sys; s=json.load(open(sys.argv[1])); d=s['scene_definition']; d['node_tags']=[t + 100000 for t in d['node_tags']]; json.dump(s, open(sys.argv[2],'w'))" "$tmp/inp-result.json" "$tmp/big-tags-result.json"
for ext in vtu vtk; do
  expect_exit 0 "export large tags as .$ext" "$sf" export "$tmp/big-tags-result.json" -o "$tmp/big-tags.$ext"
  "$debian_python" - "$tmp/inp.json" "$tmp/big-tags.$ext" <<'PY' || fail "large node tags in .$ext"
import json, sys, meshio
inp = json.load(open(sys.argv[1]))
v = meshio.read(sys.argv[2])
assert [int(t) for t in v.point_data["node_tag"]] == [t + 100000 for t in inp["node_tags"]], \
    list(v.point_data["node_tag"][:5])
PY
done
python3 -c "import json,sys; s=json.load(open(sys.argv[1])); s['node_tags'].pop(); json.dump(s, open(sys.argv[2],'w'))" "$tmp/inp.json" "$tmp/short-tags.json"
expect_exit 2 "node_tags of the wrong length" "$sf" check "$tmp/short-tags.json"
grep -qF "node_tags: 214 tags for 215 nodes" "$tmp/err" || fail "node_tags length: $(cat "$tmp/err")"
# What the deck lacks must come from --loads, each named.
expect_exit 2 "a Gmsh deck without --loads" "$sf" import "$tmp/inclusion.inp" -o "$tmp/x.json"
grep -qF "inclusion.inp: no *STEP (each step is a load case), and no load_cases: pass --loads LOADS.json" "$tmp/err" \
  || fail "no steps: $(cat "$tmp/err")"
python3 -c "import json,sys; l=json.load(open(sys.argv[1])); del l['reference']['materials']; json.dump(l, open(sys.argv[2],'w'))" \
  "$loads" "$tmp/no-material.json"
expect_exit 2 "a Gmsh deck without a material" "$sf" import "$tmp/inclusion.inp" --loads "$tmp/no-material.json"
grep -qF "inclusion.inp: no *SOLID SECTION (the elements' material): give it in $tmp/no-material.json as reference.material, or reference.materials by region (inclusion, tissue)" "$tmp/err" \
  || fail "no material: $(cat "$tmp/err")"

# A clockwise triangle: named with the fix, and still read.
python3 - "$tmp/inclusion.inp" "$tmp/inverted.inp" <<'PY' || fail "the test's inverted deck"
import sys
lines = open(sys.argv[1]).read().split("\n")
at = next(i for i, l in enumerate(lines) if l.lower().startswith("*element, type=cps3")) + 1
f = [s.strip() for s in lines[at].split(",") if s.strip()]
assert f[0] == "49", f  # the first triangle, after the 48 lines
lines[at] = ", ".join([f[0], f[2], f[1], f[3]])
open(sys.argv[2], "w").write("\n".join(lines))
PY
expect_exit 0 "a deck with a clockwise triangle" "$sf" import "$tmp/inverted.inp" --loads "$loads" -o "$tmp/inv.json"
grep -qF "inverted.inp: 1 of 380 elements are inverted (clockwise: 49); springfit solves them as they are, ccx refuses them" "$tmp/err" \
  || fail "the inverted triangle: $(cat "$tmp/err")"

# A bad element is named as the user knows it: its id in the deck (and Gmsh's tag in the .msh,
# the same number), and its nodes by theirs, not by springfit's 0-based indices.
twice=$(python3 - "$tmp/inclusion.inp" "$tmp/twice.inp" <<'PY'
import sys
lines = open(sys.argv[1]).read().split("\n")
at = next(i for i, l in enumerate(lines) if l.lower().startswith("*element, type=cps3")) + 1
f = [s.strip() for s in lines[at].split(",") if s.strip()]
assert f[0] == "49", f
lines[at] = ", ".join([f[0], f[1], f[1], f[3]])
open(sys.argv[2], "w").write("\n".join(lines))
print(f[1])  # the node listed twice
PY
) || fail "the test's deck with a node twice"
expect_exit 2 "import a deck whose triangle lists a node twice" "$sf" import "$tmp/twice.inp" --loads "$loads" -o "$tmp/twice.json"
grep -qF "(the mesh's element 49) node $twice (the mesh's tags) is listed twice" "$tmp/err" \
  || fail "the element and node named by the deck's ids: $(cat "$tmp/err")"
# Every element's tag, in the .msh's scene and the deck's, is the deck's id of an element with
# the same nodes (read from the deck's text here, not by springfit).
"$debian_python" - "$tmp/msh.json" "$tmp/inp.json" "$tmp/inclusion.inp" <<'PY' || fail "element tags"
import json, sys
deck = {}
kind = None
for line in open(sys.argv[3]).read().split("\n"):
    if line.startswith("*"):
        kind = line.lower().replace(" ", "")
        continue
    f = [x.strip() for x in line.split(",") if x.strip()]
    if kind and kind.startswith("*element,type=cps3") and len(f) == 4:
        deck[int(f[0])] = sorted(int(x) for x in f[1:])
for path in sys.argv[1:3]:
    s = json.load(open(path))
    tags, elements, node_tags = s["reference"]["element_tags"], s["reference"]["elements"], s["node_tags"]
    assert len(tags) == len(elements) == len(deck) and len(set(tags)) == len(tags), path
    for t, e in zip(tags, elements):
        assert deck[t] == sorted(node_tags[i] for i in e), (path, t)
PY

# 3D: a box of tetrahedra, whose boundary Gmsh writes as CPS3 triangles beside them.
cat >"$tmp/box.geo" <<'GEO'
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 2, 1, 1};
Mesh.MeshSizeMax = 0.5;
Physical Surface("fixed") = {1};
Physical Surface("pulled") = {2};
Physical Volume("body") = {1};
GEO
gmsh -3 "$tmp/box.geo" -o "$tmp/box.inp" >/dev/null 2>&1 || fail "gmsh -3 box"
cat >"$tmp/box-loads.json" <<'JSON'
{"reference": {"material": {"model": "linear", "young": 100, "poisson": 0.3}},
 "load_cases": [{"name": "pull", "fixed": "fixed", "tractions": [{"on": "pulled", "total": [1, 0, 0]}]},
                {"name": "shear", "fixed": "fixed", "tractions": [{"on": "pulled", "total": [0, 0.5, 0]}]}]}
JSON
expect_exit 0 "import the Gmsh 3D deck" "$sf" import "$tmp/box.inp" --loads "$tmp/box-loads.json" -o "$tmp/box.json"
grep -q "note: .*box.inp: [0-9]* CPS3 element(s) beside the [0-9]* tetrahedra left out" "$tmp/err" || fail "the boundary triangles: $(cat "$tmp/err")"
grep -q "CPS3 read as" "$tmp/err" && fail "the CPS3 note on a 3D deck, whose CPS3 are left out"
python3 -c "
import json,sys; s=json.load(open(sys.argv[1])); r=s['reference']
assert len(s['nodes'][0]) == 3 and all(len(e) == 4 for e in r['elements']), 'tetrahedra'
assert {'fixed','pulled','body'} <= set(s['node_sets']), s['node_sets'].keys()
" "$tmp/box.json" || fail "the 3D deck's scene"
expect_exit 0 "check the 3D deck" "$sf" check "$tmp/box.json"

finish gmsh_deck
