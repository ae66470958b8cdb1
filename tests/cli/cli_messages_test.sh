#!/usr/bin/env bash
# End-to-end checks of the springfit program: messages that name the file, the case and the
# field the user wrote, with the fix; units stated and carried; warnings and notices; one name
# for the springs between held nodes.
# Usage: cli_messages_test.sh SPRINGFIT SOURCE_DIR
set -u
sf=$1
src=$2
source "$(dirname "$0")/../checks.sh"

# Messages that name the file, the case and the field the user wrote, with the fix (issue 33).
gmsh "$src/examples/pipeline/inclusion.geo" -2 -o "$tmp/inclusion.msh" >/dev/null 2>&1 || fail "gmsh"
expect_exit 2 "a mesh without --loads" "$sf" run "$tmp/inclusion.msh"
grep -q "load_cases: required: a mesh carries no load cases; pass them with --loads" "$tmp/err" || fail "a mesh without --loads: $(cat "$tmp/err")"
[ "$(grep -o "inclusion.msh" "$tmp/err" | wc -l)" -eq 1 ] || fail "a mesh without --loads names the mesh once: $(cat "$tmp/err")"
# Units stated in the loads file reach the result and every export (issue 33).
"$sf" run "$tmp/inclusion.msh" --loads "$src/examples/pipeline/inclusion-loads.json" --strategy direct -q -o "$tmp/inclusion-direct.json" >"$tmp/inclusion-summary.txt" 2>&1
# The summary says them too (issue 47 item 4: every number with its unit).
grep -qx "units:             length mm, force mN, stiffness mN/mm, mass kg, time s (E is relative: no unit)" "$tmp/inclusion-summary.txt" \
  || fail "the run's summary states no units: $(head -5 "$tmp/inclusion-summary.txt")"
grep -q "^stiffness:  .*, median [0-9.e+-]* mN/mm (spread" "$tmp/inclusion-summary.txt" \
  || fail "the run's stiffness line has no unit: $(grep stiffness: "$tmp/inclusion-summary.txt")"
# And check, with its numbers' units.
"$sf" check "$tmp/inclusion.msh" --loads "$src/examples/pipeline/inclusion-loads.json" >"$tmp/inclusion-check.txt" 2>&1 || fail "check with units: $(tail -2 "$tmp/inclusion-check.txt")"
grep -qx "units:                  length mm, force mN, stiffness mN/mm, mass kg, time s (E is relative: no unit)" "$tmp/inclusion-check.txt" \
  || fail "check states no units: $(head -5 "$tmp/inclusion-check.txt")"
grep -q "young [0-9.e+-]* kPa, poisson" "$tmp/inclusion-check.txt" && grep -q "^training stiffness:     [0-9.e+-]* mN/mm$" "$tmp/inclusion-check.txt" \
  || fail "check's numbers have no units: $(grep -E 'young|training' "$tmp/inclusion-check.txt")"
python3 - "$tmp/inclusion-direct.json" <<'PY' || fail "the result carries the units"
import json, sys
r = json.load(open(sys.argv[1]))
assert r["units"] == {"length": "mm", "force": "mN", "stiffness": "mN/mm", "modulus": "kPa", "mass": "kg", "time": "s"}, r["units"]
PY
"$sf" export "$tmp/inclusion-direct.json" -o "$tmp/inclusion-model.json" >/dev/null || fail "export with units"
python3 -c "import json,sys; m=json.load(open(sys.argv[1])); assert m['units']['stiffness']=='mN/mm', m['units']" "$tmp/inclusion-model.json" || fail "the JSON model carries the units"
"$sf" export "$tmp/inclusion-direct.json" -o "$tmp/inclusion-model.vtu" >/dev/null || fail "export vtu with units"
grep -q "units: length mm, force mN, stiffness mN/mm" "$tmp/inclusion-model.vtu" || fail "the VTU model does not state its units"
"$sf" export "$tmp/inclusion-direct.json" -o "$tmp/inclusion-model.msh" >/dev/null || fail "export msh with units"
# (MSH 4.1 has no description field: a $Comments section, which gmsh itself must still read)
grep -A1 '^\$Comments$' "$tmp/inclusion-model.msh" | grep -q "units: length mm, force mN, stiffness mN/mm" \
  || fail "the Gmsh model does not state its units"
gmsh "$tmp/inclusion-model.msh" -0 -o "$tmp/inclusion-model-gmsh.msh" >/dev/null 2>&1 || fail "gmsh reads the model with its comments"
# Node-set names match without regard to case, as in a CalculiX deck.
python3 - "$src/examples/pipeline/inclusion-loads.json" "$tmp/upper-loads.json" <<'PY'
import json, sys
loads = json.load(open(sys.argv[1]))
for lc in loads["load_cases"]:
    lc["fixed"] = lc["fixed"].upper()
json.dump(loads, open(sys.argv[2], "w"))
PY
expect_exit 0 "node sets by another case" "$sf" check "$tmp/inclusion.msh" --loads "$tmp/upper-loads.json"
python3 - "$src/examples/paper-iso-5x5.json" "$tmp/on-fixed.json" "$tmp/unsupported.json" "$tmp/large.json" "$src/examples/fem-kidney-2d.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
s["node_sets"] = {"bottom": [0, 1, 2, 3, 4], "top": [20, 21, 22, 23, 24]}
s["load_cases"][0]["fixed"] = "bottom"
s["load_cases"][0]["forces"] = [{"nodes": "top", "force": [0, 0.05]}, {"nodes": "bottom", "force": [0, 0.05]}]
json.dump(s, open(sys.argv[2], "w"))
s = json.load(open(sys.argv[1]))
s["load_cases"][1]["fixed"] = []
json.dump(s, open(sys.argv[3], "w"))
plate = json.load(open(sys.argv[5]))  # (a linear material: the kidney's)
for lc in plate["load_cases"]:
    for t in lc.get("tractions", []):
        for key in ("total", "per_length", "per_area"):
            if key in t:
                t[key] = [4.0 * x for x in t[key]]
    for f in lc.get("forces", []):
        f["force"] = [4.0 * x for x in f["force"]]
json.dump(plate, open(sys.argv[4], "w"))
PY
expect_exit 2 "a force on a fixed set" "$sf" check "$tmp/on-fixed.json"
grep -q "load_cases\[0\].forces\[1\].nodes ('bottom', node_sets.bottom\[0\]): node 0 is constrained in this load case" "$tmp/err" || fail "a force on a fixed set names the force: $(cat "$tmp/err")"
expect_exit 2 "a case without supports" "$sf" check "$tmp/unsupported.json"
grep -q "load_cases\[1\]: case '[^']*': its \`fixed\` and \`displacements\` leave rigid motion free" "$tmp/err" || fail "a case without supports names the case: $(cat "$tmp/err")"
# A linear material strained past small strain (issue 50 item 1): a WARNING naming the element
# and the nonlinear materials to use, not silence; the kidney's named loads give none.
"$sf" check "$tmp/large.json" >"$tmp/large.txt" 2>&1 || fail "check of a large-load scene"
grep -q "^WARNING: .*the linear reference is loaded past small strain under the named loads" "$tmp/large.txt" || fail "no small-strain warning on a large load: $(tail -3 "$tmp/large.txt")"
grep -q "neo_hookean" "$tmp/large.txt" || fail "the small-strain warning names no nonlinear material"
# A run on it: the verdict is doubtful (exit 12) and says why on a WARNING line.
expect_exit 12 "a run fitted to a linear reference past small strain" "$sf" run "$tmp/large.json"
grep -q "^verdict: *doubtful: " "$tmp/out" || fail "no doubtful verdict: $(grep verdict "$tmp/out")"
grep -q "^WARNING: .*the linear reference is loaded past small strain" "$tmp/out" || fail "the run's verdict does not say the strain: $(grep WARNING "$tmp/out")"
"$sf" check "$src/examples/fem-kidney-2d.json" >"$tmp/small-check.txt" 2>&1
! grep -q "^notice:\|^WARNING:" "$tmp/small-check.txt" || fail "a notice on the kidney's small loads"
# A 3D geometry meshed with gmsh -2: the hint to mesh it with -3.
cat >"$tmp/box.geo" <<'GEO'
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 1, 1};
Physical Surface("skin") = {1, 2, 3, 4, 5, 6};
Physical Volume("body") = {1};
GEO
gmsh "$tmp/box.geo" -2 -o "$tmp/box-surface.msh" >/dev/null 2>&1 || fail "gmsh box"
expect_exit 2 "a 3D geometry meshed in 2D" "$sf" import "$tmp/box-surface.msh" -o "$tmp/box.json"
grep -q "mesh it with \`gmsh -3\`" "$tmp/err" || fail "no -3 hint: $(cat "$tmp/err")"
# check lists many pairs eight to a line: every case holds the same three rows of the grid.
python3 - "$src/examples/paper-iso-5x5.json" "$tmp/held-rows.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
for lc in s["load_cases"]:
    lc["fixed"] = list(range(15))
    for f in lc.get("forces", []):
        f["nodes"] = [n for n in f.get("nodes", []) if n >= 15] or [20, 21, 22, 23, 24]
json.dump(s, open(sys.argv[2], "w"))
PY
"$sf" check "$tmp/held-rows.json" >"$tmp/held-check.txt" 2>&1 || fail "check of the held rows: $(tail -2 "$tmp/held-check.txt")"
[ "$(grep -c "^    (" "$tmp/held-check.txt")" -ge 2 ] || fail "check does not wrap its pairs: $(grep -m1 "held nodes" "$tmp/held-check.txt" | cut -c1-200)"
# ... at most three lines of them, then how many more; --all-pairs lists every one (issue 47
# item 7: 635 pairs over 80 lines).
grep -q "^    \.\.\. and [0-9]* more (springfit check --all-pairs lists them)" "$tmp/held-check.txt" || fail "check does not cut a long pair list: $(grep -A4 "held nodes" "$tmp/held-check.txt" | cut -c1-120)"
[ "$(grep -A4 "^between held nodes" "$tmp/held-check.txt" | grep -c "^    (")" -le 3 ] || fail "check lists more than three lines of pairs"
# One name for one thing (issue 47 item 5): the springs between held nodes are counted by the
# same words and number in check, run's verdict and springs lines, and export.
held=$(sed -n 's/^between held nodes: *\([0-9]*\) springs.*/\1/p' "$tmp/held-check.txt")
[ -n "$held" ] && [ "$held" -gt 0 ] || fail "check names the springs between held nodes: $(grep -m1 "held nodes" "$tmp/held-check.txt" | cut -c1-120)"
# (They are unseen too: check's unseen count says it leaves them out, rather than "0" beside them.)
grep -q "^unseen springs: *[0-9]* besides the $held between held nodes" "$tmp/held-check.txt" || fail "check's unseen line: $(grep -m1 '^unseen' "$tmp/held-check.txt")"
"$sf" run "$tmp/held-rows.json" --strategy direct -o "$tmp/held-result.json" >"$tmp/held-run.txt" 2>&1
grep -q "^verdict: .* (+$held between held nodes, in exports)" "$tmp/held-run.txt" || fail "run's verdict: $(grep -m1 '^verdict' "$tmp/held-run.txt")"
grep -q "^springs: .* (+$held between held nodes: no load case sees them" "$tmp/held-run.txt" || fail "run's springs line: $(grep -m1 '^springs' "$tmp/held-run.txt")"
"$sf" export "$tmp/held-result.json" -o "$tmp/held.vtk" >"$tmp/held-export.txt" 2>&1 || fail "export of the held rows: $(cat "$tmp/held-export.txt")"
grep -q "not determined by the data: $held between held nodes" "$tmp/held-export.txt" || fail "export's count: $(head -1 "$tmp/held-export.txt")"
! grep -qi "unidentifiable\|no load case sees," "$tmp/held-check.txt" "$tmp/held-run.txt" "$tmp/held-export.txt" || fail "an old name is left"
"$sf" check "$tmp/held-rows.json" --all-pairs >"$tmp/held-all.txt" 2>&1 || fail "check --all-pairs"
! grep -q "more (springfit check --all-pairs" "$tmp/held-all.txt" || fail "check --all-pairs still cuts the list"
[ "$(grep -c "^    (" "$tmp/held-all.txt")" -gt "$(grep -c "^    (" "$tmp/held-check.txt")" ] || fail "check --all-pairs lists no more pairs"
grep -v "^description:" "$tmp/held-check.txt" | awk 'length > 200 { exit 1 }' || fail "check prints a line longer than 200 characters"

finish cli_messages
