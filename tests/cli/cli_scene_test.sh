#!/usr/bin/env bash
# End-to-end checks of the springfit program: check, example and eval (a scene read, written and evaluated;
# no search), their outputs and exit codes.
# Usage: cli_scene_test.sh SPRINGFIT SOURCE_DIR
set -u
sf=$1
src=$2
source "$(dirname "$0")/../checks.sh"

# A 3D scene whose nodes all have z = 0 (a 2D model written with z, as VTK tools do) is named
# at its nodes, not later as a mechanism or a rigid-motion error.
python3 - "$src/examples/paper-iso-5x5.json" "$tmp/flat3d.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
s["nodes"] = [p + [0.0] for p in s["nodes"]]
for lc in s["load_cases"]:
    for f in lc.get("forces", []):
        f["force"] = f["force"] + [0.0]
open(sys.argv[2], "w").write(json.dumps(s))
PY
expect_exit 2 "flat 3D scene" "$sf" check "$tmp/flat3d.json"
grep -q "nodes: all 25 nodes lie in one plane: a 3D model of them has no stiffness across it .*; for a plane model write each node as \[x, y\]" "$tmp/err" \
  || fail "flat 3D scene named at its nodes: $(cat "$tmp/err")"

# check: valid scene 0, invalid scene 2 with the path on one line, missing file 2, usage 64.
expect_exit 0 "check valid" "$sf" check "$src/examples/kidney-2d.json"
grep -q "genes:" "$tmp/out" || fail "check prints the genes"
grep -q "dependent groups:       0" "$tmp/out" || fail "check prints the identifiability report"
python3 - "$src/examples/paper-iso-5x5.json" "$tmp/one-case.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
s["load_cases"] = s["load_cases"][:1]
json.dump(s, open(sys.argv[2], "w"))
PY
expect_exit 0 "check one load case" "$sf" check "$tmp/one-case.json"
grep -q "to separate them: add a load case with a force on node" "$tmp/out" || fail "check suggests a load case: $(grep -A2 'dependent' "$tmp/out")"
expect_exit 2 "check invalid" "$sf" check "$src/tests/data/invalid-index.json"
grep -q "reference.springs\[5\]\[1\]: node index 7 out of range" "$tmp/err" || fail "check names the path: $(cat "$tmp/err")"
[ "$(wc -l <"$tmp/err")" -eq 1 ] || fail "one error line"
expect_exit 2 "check missing file" "$sf" check "$tmp/nope.json"
expect_exit 64 "check no argument" "$sf" check
expect_exit 64 "unknown subcommand" "$sf" frobnicate

# example: writes what is committed under examples/.
for name in paper-iso-5x5 paper-aniso-5x5 kidney-2d grid3d-4x4x4 stiff-2d fem-plate-5x5 fem-kidney-2d fem-kidney-2d-nl fem-kidney-2d-fine fem-block-3d; do
  expect_exit 0 "example $name" "$sf" example "$name" -o "$tmp/$name.json"
  cmp -s "$tmp/$name.json" "$src/examples/$name.json" || fail "examples/$name.json differs from 'springfit example $name'"
done
expect_exit 2 "unknown example" "$sf" example nonesuch

# eval: the reference costs exactly 0; --json carries the documented fields.
expect_exit 0 "eval json" "$sf" eval "$src/examples/paper-iso-5x5.json" --json
python3 - "$tmp/out" <<'PY' || fail "eval --json content"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["cost"] == 0 and j["normalized_error"] == 0 and j["mechanism"] is False, j
assert len(j["load_cases"]) == 7
for lc in j["load_cases"]:
    assert {"cost", "iterations", "residual"} <= lc.keys(), lc
PY
expect_exit 0 "eval all" "$sf" eval "$src/examples/paper-aniso-5x5.json" --topology all
grep -q "normalized error:  0.30" "$tmp/out" || fail "eval all prints the error: $(head -3 "$tmp/out")"
echo '{"springs": [[0, 1], [0, 5]]}' >"$tmp/topo.json"
expect_exit 0 "eval topology file (mechanism)" "$sf" eval "$src/examples/paper-iso-5x5.json" --topology "$tmp/topo.json" --json
python3 -c "import json,sys; j=json.load(open('$tmp/out')); assert j['mechanism'] is True and j['cost'] > 0" || fail "mechanism flagged"
echo '{"springs": [[0, 24]]}' >"$tmp/bad-topo.json"
expect_exit 2 "eval bad topology" "$sf" eval "$src/examples/paper-iso-5x5.json" --topology "$tmp/bad-topo.json"
grep -q "springs\[0\]" "$tmp/err" || fail "bad topology names springs[0]: $(cat "$tmp/err")"

finish cli_scene
