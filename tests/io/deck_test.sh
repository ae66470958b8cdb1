#!/usr/bin/env bash
# springfit import of CalculiX/Abaqus decks (.inp): the decks tests/fem/ccx_reference.py writes
# for the FEM examples (one per load case, linear and NLGEOM) imported together give back
# the example's equilibria; trusses give an MSS reference; sets, GENERATE, *INCLUDE and
# model-level *BOUNDARY read; what is not read is an error naming the file and line.
# Usage: deck_test.sh SPRINGFIT SOURCE_DIR
set -u
sf=$1
src=$2
source "$(dirname "$0")/../checks.sh"
command -v ccx >/dev/null || { echo "FAIL: ccx is missing: run scripts/install-deps.sh"; exit 1; }

# The example's decks, imported together: its equilibria to round-off.
for example in fem-kidney-2d fem-kidney-2d-nl; do
  mkdir -p "$tmp/$example"
  python3 "$src/tests/fem/ccx_reference.py" "$src/examples/$example.json" --workdir "$tmp/$example" \
    -o "$tmp/$example/ccx.json" || fail "$example: ccx_reference.py"
  mapfile -t decks < <(ls "$tmp/$example"/case_*.inp | sort)
  expect_exit 0 "import $example decks" "$sf" import "${decks[@]}" -o "$tmp/$example/scene.json"
  expect_exit 0 "reference of the decks" "$sf" reference "$tmp/$example/scene.json" --json
  cp "$tmp/out" "$tmp/$example/ours.json"
  expect_exit 0 "reference of $example" "$sf" reference "$src/examples/$example.json" --json
  python3 - "$tmp/$example/scene.json" "$tmp/$example/ours.json" "$tmp/out" "$example" <<'PY' || fail "$example: the decks are not the example"
import json, sys
scene, deck_ref, example_ref = (json.load(open(f)) for f in sys.argv[1:4])
nl = sys.argv[4].endswith("-nl")
m = scene["reference"]["material"]
assert m["model"] == ("st_venant_kirchhoff" if nl else "linear") and m["poisson"] == 0.45, m
assert scene["reference"]["plane"] == "strain" and len(scene["load_cases"]) == 7
assert [c["name"] for c in scene["load_cases"]] == ["case_%02d" % k for k in range(7)]
a, b = deck_ref["reference"]["positions"], example_ref["reference"]["positions"]
assert len(a) == len(b) == 7
worst = max(abs(x - y) for ca, cb in zip(a, b) for pa, pb in zip(ca, cb) for x, y in zip(pa, pb))
assert worst < 1e-9 * 10, worst  # the kidney is 10 long
PY
done

# CalculiX's results as a positions reference: the .dat files (*NODE PRINT) the harness read,
# and .frd files (*NODE FILE) from the same decks with U requested.
kid="$tmp/fem-kidney-2d"
mapfile -t decks < <(ls "$kid"/case_*.inp | sort)
mapfile -t dats < <(ls "$kid"/case_*.dat | sort)
expect_exit 0 "import with .dat results" "$sf" import "${decks[@]}" --results "${dats[@]}" -o "$kid/dat.json"
for deck in "${decks[@]}"; do
  frd_deck="${deck%.inp}-frd.inp"
  sed 's/^\*END STEP/*NODE FILE\nU\n*END STEP/' "$deck" >"$frd_deck"
  (cd "$kid" && ccx -i "$(basename "${frd_deck%.inp}")" >/dev/null 2>&1) || fail "ccx on $frd_deck"
done
mapfile -t frds < <(ls "$kid"/case_*-frd.frd | sort)
expect_exit 0 "import with .frd results" "$sf" import "${decks[@]}" --results "${frds[@]}" -o "$kid/frd.json"
python3 - "$kid/dat.json" "$kid/frd.json" "$kid/ccx.json" <<'PY' || fail "the results as positions"
import json, sys
dat, frd, ccx = (json.load(open(f)) for f in sys.argv[1:4])
assert dat["reference"]["type"] == "positions" and dat["candidates"]["type"] == "pairs"
assert len(dat["candidates"]["pairs"]) == 263  # the kidney's mesh edges
assert dat["search"] == {"strategy": "continuous", "response": "linear"}, dat.get("search")
assert dat["reference"]["positions"] == ccx["reference"]["positions"]  # the harness read the same .dat
a, b = frd["reference"]["positions"], dat["reference"]["positions"]
worst = max(abs(x - y) for ca, cb in zip(a, b) for pa, pb in zip(ca, cb) for x, y in zip(pa, pb))
assert worst < 1e-5, worst  # .frd prints 6 significant digits
PY
expect_exit 0 "check the positions scene" "$sf" check "$kid/dat.json"
# Per-spring stiffness on the mesh edges reproduces an FEM model's answers: the default run of
# the imported results is continuous, and close.
expect_exit 0 "run the positions scene" "$sf" run "$kid/dat.json" --json -q
python3 - "$tmp/out" <<'PY' || fail "the results' run: $(head -c 300 "$tmp/out")"
import json, sys
r = json.load(open(sys.argv[1]))
# (nu 0.45 in plane strain: the mesh's springs reach E 0.046, the closed-form ones 0.33.)
assert r["ran"] == "continuous" and r["rms_error"] < 0.1, (r["ran"], r.get("rms_error"))
assert "generalization" not in r  # positions cannot be probed
PY
# The short record format (nodes in 5 columns, format flag 0 in column 75 of 100CL) reads alike.
python3 - "${frds[@]}" <<'PY' || fail "writing short-format .frd files"
import sys
for path in sys.argv[1:]:
    out = []
    for line in open(path).read().split("\n"):
        if line.startswith("  100CL") and len(line) >= 75:
            line = line[:74] + "0" + line[75:]
        elif line.startswith(" -1") and len(line) > 13 and "DISP" not in line:
            line = line[:3] + line[8:13] + line[13:]
        out.append(line)
    open(path.replace("-frd.frd", "-short.frd"), "w").write("\n".join(out))
PY
mapfile -t shorts < <(ls "$kid"/case_*-short.frd | sort)
expect_exit 0 "import with short .frd results" "$sf" import "${decks[@]}" --results "${shorts[@]}" -o "$kid/short.json"
python3 -c "import json,sys; a,b=(json.load(open(f))['reference'] for f in sys.argv[1:3]); assert a == b" "$kid/short.json" "$kid/frd.json" \
  || fail "short-format .frd reads as the long one"
expect_exit 2 "results of fewer steps" "$sf" import "${decks[@]}" --results "${dats[0]}"
grep -qF -- "--results: 1 steps of results for 7 load cases" "$tmp/err" || fail "results count: $(cat "$tmp/err")"
expect_exit 2 "a .frd without displacements" "$sf" import "${decks[0]}" --results "${decks[0]%.inp}.frd"
grep -qF "no displacements (DISP) in the file: ask ccx for them with *NODE FILE and U" "$tmp/err" || fail "frd without DISP: $(cat "$tmp/err")"
expect_exit 2 "results with a mesh" "$sf" import "$tmp/none.msh" --results "${dats[0]}"

# *DLOAD pressures on tetrahedron faces (P1 to P4): a 2 x 2 x 1 block of Kuhn tetrahedra,
# bottom held, a pressure on every top face and a shear-free push on one side; springfit's
# equilibrium of the imported deck against ccx's of the same deck.
python3 - "$tmp/dload.inp" <<'PY'
import itertools, sys
n = (3, 3, 2)
ids = {}
lines = ["*NODE, NSET=NALL"]
for z, y, x in itertools.product(range(n[2]), range(n[1]), range(n[0])):
    ids[x, y, z] = len(ids) + 1
    lines.append("%d, %g, %g, %g" % (ids[x, y, z], x, y, z))
coord_of = lambda v: next(k for k, w in ids.items() if w == v)
tets = []
for x, y, z in itertools.product(range(n[0] - 1), range(n[1] - 1), range(n[2] - 1)):
    c = lambda dx, dy, dz: ids[x + dx, y + dy, z + dz]
    for path in itertools.permutations(range(3)):  # Kuhn: 0 -> 7 along the axes in each order
        p = [0, 0, 0]
        corners = [c(*p)]
        for axis in path:
            p[axis] = 1
            corners.append(c(*p))
        at = [coord_of(v) for v in corners]
        e = [[at[k][a] - at[0][a] for a in range(3)] for k in (1, 2, 3)]
        volume = (e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0])
                  + e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]))
        if volume < 0:  # CalculiX wants positive orientation
            corners[1], corners[2] = corners[2], corners[1]
        tets.append(corners)
faces = [(0, 1, 2), (0, 3, 1), (1, 3, 2), (2, 3, 0)]  # P1..P4
coord = {v: k for k, v in ids.items()}
lines.append("*ELEMENT, TYPE=C3D4, ELSET=EALL")
top, side = [], []
for e, t in enumerate(tets, 1):
    lines.append("%d, %d, %d, %d, %d" % ((e,) + tuple(t)))
    for f, face in enumerate(faces, 1):
        pts = [coord[t[k]] for k in face]
        if all(p[2] == n[2] - 1 for p in pts):
            top.append("%d, P%d, 0.3" % (e, f))
        if all(p[0] == n[0] - 1 for p in pts):
            side.append("%d, P%d, 0.1" % (e, f))
lines += ["*MATERIAL, NAME=M", "*ELASTIC", "100, 0.3", "*SOLID SECTION, ELSET=EALL, MATERIAL=M",
          "*NSET, NSET=BOTTOM"] + [str(v) for k, v in ids.items() if k[2] == 0]
lines += ["*BOUNDARY", "BOTTOM, 1, 3", "*STEP, NAME=press", "*STATIC", "*DLOAD"] + top + side
lines += ["*NODE PRINT, NSET=NALL", "U", "*END STEP", ""]
assert top and side
open(sys.argv[1], "w").write("\n".join(lines))
PY
(cd "$tmp" && ccx -i dload >/dev/null 2>&1) || fail "ccx on the DLOAD deck"
expect_exit 0 "import the DLOAD deck" "$sf" import "$tmp/dload.inp" --results "$tmp/dload.dat" -o "$tmp/dload-ccx.json"
expect_exit 0 "reference of the DLOAD deck" "$sf" reference "$tmp/dload.inp" --json
python3 - "$tmp/out" "$tmp/dload-ccx.json" <<'PY' || fail "DLOAD: springfit's equilibrium is not ccx's"
import json, sys
ours = json.load(open(sys.argv[1]))["reference"]["positions"][0]
ccx = json.load(open(sys.argv[2]))["reference"]["positions"][0]
worst = max(abs(a - b) for p, q in zip(ours, ccx) for a, b in zip(p, q))
moved = max(abs(a - b) for p, q in zip(ccx, json.load(open(sys.argv[2]))["nodes"]) for a, b in zip(p, q))
assert moved > 1e-3 and worst < 1e-6 * moved * 100, (worst, moved)  # ccx prints 7 digits
PY

# A hand-written deck: trusses (an MSS reference, k = E A / L), sets by GENERATE, *INCLUDE,
# a model-level *BOUNDARY held in every step, a prescribed displacement, two named steps.
cat >"$tmp/nodes.inp" <<'INP'
*NODE, NSET=ALL
1, 0, 0
2, 1, 0
3, 2, 0
4, 0, 1
5, 1, 1
6, 2, 1
INP
cat >"$tmp/truss.inp" <<'INP'
** a 2 x 1 truss frame
*INCLUDE, INPUT=nodes.inp
*ELEMENT, TYPE=T2D2, ELSET=BARS
1, 1, 2
2, 2, 3
3, 4, 5
4, 5, 6
5, 1, 4
6, 2, 5
7, 3, 6
8, 1, 5
9, 2, 6
*NSET, NSET=LEFT, GENERATE
1, 4, 3
*NSET, NSET=Right
3, 6
*MATERIAL, NAME=STEEL
*ELASTIC
200, 0.3
*SOLID SECTION, ELSET=BARS, MATERIAL=STEEL
0.5
*BOUNDARY
LEFT, 1, 2
*STEP, NAME=pull
*STATIC
*CLOAD
right, 1, 0.1
*NODE PRINT, NSET=ALL
U
*END STEP
*STEP, NAME=lift
*STATIC
*CLOAD, OP=NEW
*BOUNDARY
6, 1, 1, 0
6, 2, 2, 0.01
*END STEP
INP
expect_exit 0 "import the truss deck" "$sf" import "$tmp/truss.inp" -o "$tmp/truss.json"
python3 - "$tmp/truss.json" <<'PY' || fail "the truss deck"
import json, math, sys
s = json.load(open(sys.argv[1]))
r = s["reference"]
assert r["type"] == "mss" and len(r["springs"]) == 9
for (a, b), k in zip(r["springs"], r["stiffness"]):
    length = math.dist(s["nodes"][a], s["nodes"][b])
    assert abs(k - 200 * 0.5 / length) < 1e-12 * k, (a, b, k)
assert s["node_sets"]["LEFT"] == [0, 3] and s["node_sets"]["Right"] == [2, 5]
pull, lift = s["load_cases"]
assert pull["name"] == "pull" and pull["fixed"] == [0, 3]
assert sorted(f["node"] for f in pull["forces"]) == [2, 5] and all(f["force"] == [0.1, 0] for f in pull["forces"])
assert lift["fixed"] == [0, 3] and lift["displacements"] == [{"node": 5, "displacement": [0, 0.01]}]
PY
expect_exit 0 "check the truss deck" "$sf" check "$tmp/truss.inp"

# What is not read: the file, the line, the reason; exit 2.
bad_deck() {  # what text-to-replace replacement expected-message
  python3 -c "import sys; s=open(sys.argv[1]).read(); assert sys.argv[2] in s; open(sys.argv[3],'w').write(s.replace(sys.argv[2], sys.argv[4], 1))" \
    "$tmp/truss.inp" "$2" "$tmp/bad.inp" "$3" || { fail "$1: the test's replacement"; return; }
  expect_exit 2 "$1" "$sf" import "$tmp/bad.inp" -o "$tmp/bad.json"
  grep -qF -- "$4" "$tmp/err" || fail "$1: $(cat "$tmp/err")"
}
bad_deck "DLOAD on trusses" "*CLOAD" "*DLOAD" "bad.inp:27: *DLOAD 1: springfit reads uniform pressures P1 to P4 on C3D4 faces only"
bad_deck "an unknown keyword" "*STATIC" "*EQUATION" "bad.inp:25: *EQUATION is not read by springfit and may change the mechanics"
bad_deck "an element type" "TYPE=T2D2" "TYPE=CPS4" "bad.inp:3: element type 'CPS4': springfit reads CPS3, CPE3"
bad_deck "a partial boundary" "LEFT, 1, 2" "LEFT, 1, 1" "bad.inp:23: node 1 is held in 1 of its 2 directions"
bad_deck "an inherited load" "*CLOAD, OP=NEW
" "" "bad.inp:31: step 2 ('lift') inherits the earlier steps' loads in CalculiX; springfit's load cases start from rest"
bad_deck "a parameter not read" "*NSET, NSET=Right" "*NSET, NSET=Right, ELSET=BARS" "bad.inp:15: *NSET: parameter ELSET is not read by springfit"
bad_deck "extra fields" "LEFT, 1, 2" "LEFT, 1, 2, 0, 7" "bad.inp:23: *BOUNDARY takes 4 fields at most"
bad_deck "a truss without its area" "*SOLID SECTION, ELSET=BARS, MATERIAL=STEEL
0.5" "*SOLID SECTION, ELSET=BARS, MATERIAL=STEEL" "a truss section needs its cross-section area"
bad_deck "an unknown set" "right, 1, 0.1" "middle, 1, 0.1" "bad.inp:27: unknown node set 'middle'"
bad_deck "a bad number" "200, 0.3" "2OO, 0.3" "bad.inp:19: expected a number for E, got '2OO'"
bad_deck "an unended step" "*END STEP
*STEP, NAME=lift" "*STEP, NAME=lift" "*STEP inside a step"
expect_exit 2 "a missing deck" "$sf" import "$tmp/none.inp"
grep -qF "none.inp: no such file" "$tmp/err" || fail "a missing deck: $(cat "$tmp/err")"

finish deck
