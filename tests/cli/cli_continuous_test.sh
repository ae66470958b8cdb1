#!/usr/bin/env bash
# End-to-end checks of the springfit program: strategy continuous fitted to the named cases
# (the sparsity path, the size limit, the trade-off figure, the regularisation) and the options
# it refuses, outputs and exit codes.
# Usage: cli_continuous_test.sh SPRINGFIT SOURCE_DIR
set -u
sf=$1
src=$2
source "$(dirname "$0")/cli_support.sh"  # (and ../checks.sh)

# A result without a sparsity path (cli_run_test.sh checks it).
paper_result "$tmp/result.json"

# Strategy continuous fitted to the named cases alone (--probes none): the response, the
# sparsity path, the size limit from the command line, and the trade-off figure.
expect_exit 0 "run fem continuous" "$sf" run "$src/examples/fem-plate-5x5.json" --probes none --max-springs 70 -q -o "$tmp/continuous.json"
grep -q "^response:          linear" "$tmp/out" || fail "run prints the response: $(cat "$tmp/out")"
grep -q "^sparsity path:" "$tmp/out" || fail "run prints the sparsity path: $(cat "$tmp/out")"
python3 - "$tmp/continuous.json" <<'PY' || fail "continuous result: $(head -c 300 "$tmp/continuous.json")"
import json, sys
r = json.load(open(sys.argv[1]))
c = r["continuous"]
assert r["identify"] == "topology_and_stiffness" and r["response"] == "linear", r["identify"]
assert len(r["springs"]) <= 70 and len(r["stiffness"]) == len(r["springs"])
assert c["started_from"] == "baseline" and len(c["path"]) >= 2
assert c["path"][c["chosen"]]["springs"] <= 70
assert all(a["springs"] > b["springs"] for a, b in zip(c["path"], c["path"][1:]))
assert r["rms_error"] < r["baseline"]["rms_error"]
assert r["scene_definition"]["search"]["max_springs"] == 70
assert "generalization" not in r and r["options"]["probes"] == "none"
PY
expect_exit 0 "plot tradeoff" "$sf" plot --tradeoff "$tmp/continuous.json" -o "$tmp/tradeoff.svg"
python3 - "$tmp/tradeoff.svg" "$tmp/continuous.json" <<'PY' || fail "tradeoff plot content"
import json, sys, xml.etree.ElementTree as ET
ns = "{http://www.w3.org/2000/svg}"
svg = ET.parse(sys.argv[1])
path = json.load(open(sys.argv[2]))["continuous"]["path"]
lines = [e for e in svg.iter(ns + "polyline") if e.get("class") == "curve0"]
assert len(lines) == 1 and len(lines[0].get("points").split()) == len(path)
assert sum(1 for e in svg.iter(ns + "line") if e.get("class") == "reference") == 2  # level + legend
# The returned model is drawn (a square) and named with the result's own springs and E.
r = json.load(open(sys.argv[2]))
assert sum(1 for e in svg.iter(ns + "rect") if e.get("class") == "curve0") == 1
text = " ".join(e.text or "" for e in svg.iter(ns + "text"))
assert f"returned model (square): {len(r['springs'])} springs, E {r['rms_error']:.3g}" in text, text
assert f"path point {r['continuous']['chosen'] + 1} of {len(path)}" in text, text
PY
expect_exit 2 "plot tradeoff without a path" "$sf" plot --tradeoff "$tmp/result.json" -o "$tmp/x.svg"
grep -q "has no sparsity path" "$tmp/err" || fail "tradeoff names what is missing: $(cat "$tmp/err")"
expect_exit 2 "max-springs with hybrid" "$sf" run "$src/examples/paper-iso-5x5.json" --strategy hybrid --max-springs 5
grep -q "search.max_springs: chooses a point of the sparsity path" "$tmp/err" || fail "max-springs needs continuous: $(cat "$tmp/err")"
# An option the strategy that runs ignores is refused, naming the one that acts (issue 33).
expect_exit 2 "target with continuous" "$sf" run "$src/examples/fem-plate-5x5.json" --target 0.01
grep -q "search.target_normalized_error: is read by the genetic search only (--target).*--target-error" "$tmp/err" || fail "--target with continuous names --target-error: $(cat "$tmp/err")"
# The regularisation: auto cross-validates each strength and runs with the lowest held-out E.
expect_exit 0 "run regularization auto" "$sf" run "$src/examples/fem-plate-5x5.json" --probes none --regularization auto -o "$tmp/regularized.json"
grep -q "^regularization:    .*, the lowest held-out E of those tried (0: .*, 0.001: .*, 0.01: .*, 0.1: " "$tmp/out" || fail "run prints the regularisation: $(cat "$tmp/out")"
grep -q "^  worst predicted: 'stretch +x'" "$tmp/out" || fail "run names the worst predicted case: $(cat "$tmp/out")"
python3 - "$tmp/regularized.json" <<'PY' || fail "regularization result: $(head -c 300 "$tmp/regularized.json")"
import json, sys
r = json.load(open(sys.argv[1]))
g = r["continuous"]["regularization"]
assert g["chosen_by"] == "held_out" and [t["strength"] for t in g["tried"]] == [0, 0.001, 0.01, 0.1], g
best = min(g["tried"], key=lambda t: t["held_out_rms_error"])
assert g["strength"] == best["strength"], g
assert r["options"]["regularization"] == "auto" and r["scene_definition"]["search"]["regularization"] == "auto"
PY
expect_exit 0 "run regularization 0.01" "$sf" run "$src/examples/fem-plate-5x5.json" --probes none --regularization 0.01 -q -o "$tmp/regularized.json"
python3 - "$tmp/regularized.json" "$tmp/continuous.json" <<'PY' || fail "a set regularisation: $(head -c 300 "$tmp/regularized.json")"
import json, sys
r = json.load(open(sys.argv[1]))
g = r["continuous"]["regularization"]
assert g == {"strength": 0.01, "chosen_by": "setting", "tried": []}, g
assert r["continuous"]["fit_rms_error"] > json.load(open(sys.argv[2]))["continuous"]["fit_rms_error"]
PY
expect_exit 2 "bad regularization" "$sf" run "$src/examples/fem-plate-5x5.json" --regularization strong
grep -q -- "--regularization: must be \"auto\" or a finite number >= 0, got 'strong'" "$tmp/err" || fail "regularization names the value: $(cat "$tmp/err")"
expect_exit 2 "regularization with hybrid" "$sf" run "$src/examples/paper-iso-5x5.json" --strategy hybrid --regularization 0.1
grep -q "search.regularization: regularises the continuous fit" "$tmp/err" || fail "regularization needs continuous: $(cat "$tmp/err")"
expect_exit 2 "bad response" "$sf" run "$src/examples/fem-plate-5x5.json" --response small
grep -q -- "--response: unknown value 'small' (expected linear or nonlinear)" "$tmp/err" || fail "response names the value: $(cat "$tmp/err")"

finish cli_continuous
