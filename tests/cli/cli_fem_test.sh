#!/usr/bin/env bash
# End-to-end checks of the springfit program: FEM references (check, reference, run direct on
# them) and strategy continuous fitted to probe loads (the certificate on loads never fitted,
# the verdict), outputs and exit codes.
# Usage: cli_fem_test.sh SPRINGFIT SOURCE_DIR
set -u
sf=$1
src=$2
source "$(dirname "$0")/../checks.sh"

# FEM references: check summarises, reference solves and prints positions that paste into a
# positions scene, run reports E and the closed-form baseline.
expect_exit 0 "check fem" "$sf" check "$src/examples/fem-plate-5x5.json"
grep -q "reference:              fem, 32 triangles, plane stress, thickness 1" "$tmp/out" || fail "check fem reference: $(cat "$tmp/out")"
grep -q "smallest quality:     [0-9.e-]* (element [0-9]*; 1 = equilateral)" "$tmp/out" || fail "check fem quality: $(cat "$tmp/out")"
grep -q "1 traction" "$tmp/out" || fail "check counts tractions"
expect_exit 0 "reference fem" "$sf" reference "$src/examples/fem-kidney-2d-nl.json" --json -o "$tmp/reference.json"
cmp -s "$tmp/out" "$tmp/reference.json" || fail "reference -o writes what --json prints"
python3 - "$src/examples/fem-kidney-2d-nl.json" "$tmp/reference.json" "$tmp/positions-scene.json" <<'PY' || fail "reference output"
import json, sys
scene = json.load(open(sys.argv[1]))
out = json.load(open(sys.argv[2]))
assert out["reference"]["type"] == "positions"
assert len(out["reference"]["positions"]) == len(scene["load_cases"]) == 7
assert all(len(p) == len(scene["nodes"]) for p in out["reference"]["positions"])
assert len(out["load_cases"]) == 7 and "tractions" not in out["load_cases"][0] and out["load_cases"][0]["forces"]
for c in out["solves"]:
    assert c["iterations"] >= 2 and c["load_steps"] >= 1 and c["residual"] < 1e-9, c  # nonlinear: several Newton steps
    assert 0.1 < c["max_displacement"] < 1.0, c
scene["reference"] = out["reference"]
scene["load_cases"] = out["load_cases"]
scene["candidates"] = {"type": "nearest", "k": 8}
json.dump(scene, open(sys.argv[3], "w"))
PY
expect_exit 0 "positions scene from reference" "$sf" check "$tmp/positions-scene.json"
python3 - "$src/examples/fem-plate-5x5.json" "$tmp/bad-fem.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
s["reference"]["material"]["poisson"] = 0.5
json.dump(s, open(sys.argv[2], "w"))
PY
expect_exit 2 "reference invalid fem" "$sf" reference "$tmp/bad-fem.json"
grep -q "reference.material.poisson: must be in (-1, 0.5), got 0.5" "$tmp/err" || fail "reference names the path: $(cat "$tmp/err")"
grep -q "got 0.5: an incompressible material .*use 0.49" "$tmp/err" || fail "nu 0.5 hints at 0.49: $(cat "$tmp/err")"
# Nearly incompressible is taken, with a notice on locking.
python3 - "$src/examples/fem-plate-5x5.json" "$tmp/locking-fem.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
s["reference"]["material"]["poisson"] = 0.499
json.dump(s, open(sys.argv[2], "w"))
PY
expect_exit 0 "check nu 0.499" "$sf" check "$tmp/locking-fem.json"
grep -q "^notice: .*reference.material.poisson: Poisson's ratio 0.499 is above 0.49: linear triangles lock there" "$tmp/out" || fail "nu 0.499 notes locking: $(cat "$tmp/out")"
# direct on an FEM reference: no MSS reproduces it (stop not_reproduced), but at the kidney's
# small-strain loads direct's force balance gives a usable model (E 0.081, the baseline's 0.32;
# at five times the loads, past small strain, it was worse than the rest shape).
expect_exit 0 "run fem direct" "$sf" run "$src/examples/fem-kidney-2d.json" --strategy direct --json
python3 - "$tmp/out" <<'PY' || fail "run fem reports E and the baseline: $(head -c 300 "$tmp/out")"
import json, math, sys
r = json.load(open(sys.argv[1]))
assert abs(r["rms_error"] - math.sqrt(r["normalized_error"])) < 1e-12 * r["rms_error"]
b = r["baseline"]
assert b["recipe"] == "van_gelder_1998" and b["springs"] == 263 and b["converged"], b
assert b["worse_than_baseline"] == (r["normalized_error"] > b["normalized_error"]), b
assert r["stop"] == "not_reproduced" and 0 < r["normalized_error"] < 1, r["stop"]
assert "does not reproduce the reference" in r["stop_message"], r["stop_message"]
PY

# Strategy continuous (default on an FEM reference) fitted to probe loads: the certificate on
# loads it was never fitted to, beside the baseline, in the summary and the result.
expect_exit 0 "run fem probes" "$sf" run "$src/examples/fem-plate-5x5.json" -q -o "$tmp/probes.json"
grep -q "^unseen loads:      [0-9]* held-out probes on [0-9]* supports, never fitted (small-load limit): median E .*; baseline " "$tmp/out" || fail "run prints the held-out E: $(cat "$tmp/out")"
# The verdict line names them as the certificate does: held-out probes (issue 47 item 5).
grep -q "^verdict: .*, held-out probes E [0-9.e-]* (baseline [0-9.e-]*)" "$tmp/out" || fail "the verdict names the held-out probes: $(grep -m1 '^verdict' "$tmp/out")"
grep -q "^  every load:      any load on your supports is reproduced within [0-9.e+-]* of the response in the energy norm (baseline within [0-9.e+-]*); generalised eigenvalues of (K_model, K_ref) in \[" "$tmp/out" || fail "run prints the pencil's bound beside the baseline's: $(cat "$tmp/out")"
grep -q "^  any support:     on the free body (modulo rigid motions, which bounds every support) in \[" "$tmp/out" || fail "run prints the free-body bound: $(cat "$tmp/out")"
cp "$tmp/out" "$tmp/probes-summary.txt"
python3 - "$tmp/probes.json" <<'PY' || fail "probe result: $(head -c 300 "$tmp/probes.json")"
import json, sys
r = json.load(open(sys.argv[1]))
g = r["generalization"]
assert g["fitted_to_probes"] and not g["returned_baseline"], g
assert g["held_out"]["median"] < 0.5 * g["baseline_held_out"]["median"], g
assert set(g["by_family"]) == {"point", "patch", "body", "push", "grasp", "named"}, g["by_family"]
assert g["lambda_min"] > 0.1 and g["lambda_max"] >= g["lambda_min"], g
assert g["probes"]["held_out"] > 0 and g["probes"]["supports"] >= 3, g["probes"]
assert r["options"]["probes"] == "auto"
# Issue 47: the options as the probe fit reads them, none of the genetic search's, and its
# regularisation the continuation's (beside the strength it chose), not a 0 beside 1e-06.
assert "population" not in r["options"] and "crossover" not in r["options"], r["options"]
assert r["options"]["regularization"] == "continuation" and g["fit"]["regularization"] > 0, r["options"]
fb = g["free_body"]
assert fb["model"]["lambda_min"] <= g["lambda_min"] * (1 + 1e-9) and fb["baseline"]["bound"] is not None, fb
PY
python3 - "$tmp/kidney-steps.json" "$src/examples/fem-kidney-2d.json" "$sf" <<'PY' || fail "the summary's steps are the fit's"
import json, subprocess, sys
p = subprocess.run([sys.argv[3], "run", sys.argv[2], "-o", sys.argv[1]], capture_output=True, text=True)
out = p.stdout
r = json.load(open(sys.argv[1]))
steps = r["continuous"]["steps"]
assert steps > 0 and f"steps:             {steps} (Gauss-Newton steps of the probe fit)" in out, (steps, out)
# The progress line's last "fit step N" is the same N (it said 0 beside 21 once).
fit_lines = [l for l in p.stderr.splitlines() if l.startswith("fit step ")]
assert fit_lines and fit_lines[-1].startswith(f"fit step {steps} "), (steps, fit_lines[-3:])
PY
# A requested probe count: the generated probes are about that many, with the tool loads (8
# pushes and 6 grasps on each of the 5 supports) on top.
expect_exit 0 "run fem probes 60" "$sf" run "$src/examples/fem-plate-5x5.json" --probes 60 -q -o "$tmp/probes60.json"
python3 - "$tmp/probes60.json" <<'PY' || fail "probe count: $(head -c 300 "$tmp/probes60.json")"
import json, sys
r = json.load(open(sys.argv[1]))
assert r["scene_definition"]["search"]["probes"] == 60 and r["options"]["probes"] == 60
assert 120 <= r["generalization"]["probes"]["total"] - len(r["load_cases"]) <= 140, r["generalization"]["probes"]
PY
# (The kidney's certificate bound, 6.4, is worse than the recipe's 4.18 by more than a quarter:
# a doubtful verdict, exit 12, with the WARNING saying it; proto/RUN.md, "Doubts".)
expect_exit 12 "run fem kidney doubtful" "$sf" run "$src/examples/fem-kidney-2d.json" -q -o "$tmp/kidney.json"
grep -q "^WARNING: *the certificate: a load on your supports can move the model by up to [0-9.]* times" "$tmp/out" || fail "the doubt is not said: $(grep -E 'verdict|WARNING' "$tmp/out")"
# and where to read what changes it (a new user's trial found no hint).
grep -A1 "^WARNING:" "$tmp/out" | tail -1 | grep -q '^what to try: *proto/RUN.md, "What to try"' || fail "no hint after the doubts: $(grep -A1 -E 'WARNING' "$tmp/out" | tail -2)"
grep -q '^### What to try$' "$src/proto/RUN.md" || fail "proto/RUN.md has no section What to try"
# The export of that model says the same where it states the verdict.
expect_exit 0 "export doubtful kidney" "$sf" export "$tmp/kidney.json" -o "$tmp/kidney.vtk"
grep -q 'verdict doubtful: .*; what to try: proto/RUN.md, "What to try"' "$tmp/out" || fail "the export does not point to what to try: $(cat "$tmp/out")"
expect_exit 2 "bad probes" "$sf" run "$src/examples/fem-plate-5x5.json" --probes many
grep -q -- "--probes: must be \"auto\", \"none\" or a count from 1 to 20000, got 'many'" "$tmp/err" || fail "probes names the value: $(cat "$tmp/err")"

finish cli_fem
