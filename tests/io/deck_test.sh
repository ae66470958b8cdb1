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
assert dat["reference"]["positions"] == ccx["reference"]["positions"]  # the harness read the same .dat
a, b = frd["reference"]["positions"], dat["reference"]["positions"]
worst = max(abs(x - y) for ca, cb in zip(a, b) for pa, pb in zip(ca, cb) for x, y in zip(pa, pb))
assert worst < 1e-5, worst  # .frd prints 6 significant digits
PY
expect_exit 0 "check the positions scene" "$sf" check "$kid/dat.json"
expect_exit 2 "results of fewer steps" "$sf" import "${decks[@]}" --results "${dats[0]}"
grep -qF -- "--results: 1 steps of results for 7 load cases" "$tmp/err" || fail "results count: $(cat "$tmp/err")"
expect_exit 2 "a .frd without displacements" "$sf" import "${decks[0]}" --results "${decks[0]%.inp}.frd"
grep -qF "no displacements (DISP) in the file: ask ccx for them with *NODE FILE and U" "$tmp/err" || fail "frd without DISP: $(cat "$tmp/err")"
expect_exit 2 "results with a mesh" "$sf" import "$tmp/none.msh" --results "${dats[0]}"

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
bad_deck "DLOAD" "*CLOAD" "*DLOAD" "bad.inp:26: *DLOAD (distributed loads) is not read"
bad_deck "an unknown keyword" "*STATIC" "*EQUATION" "bad.inp:25: *EQUATION is not read by springfit and may change the mechanics"
bad_deck "an element type" "TYPE=T2D2" "TYPE=CPS4" "bad.inp:3: element type 'CPS4': springfit reads CPS3, CPE3"
bad_deck "a partial boundary" "LEFT, 1, 2" "LEFT, 1, 1" "bad.inp:24: node 1 is held in 1 of its 2 directions"
bad_deck "an unknown set" "right, 1, 0.1" "middle, 1, 0.1" "bad.inp:27: unknown node set 'middle'"
bad_deck "a bad number" "200, 0.3" "2OO, 0.3" "bad.inp:19: expected a number for E, got '2OO'"
bad_deck "an unended step" "*END STEP
*STEP, NAME=lift" "*STEP, NAME=lift" "*STEP inside a step"
expect_exit 2 "a missing deck" "$sf" import "$tmp/none.inp"
grep -qF "none.inp: no such file" "$tmp/err" || fail "a missing deck: $(cat "$tmp/err")"

finish deck
