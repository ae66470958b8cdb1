#!/usr/bin/env bash
# End-to-end checks of the springfit program: outputs and exit codes.
# Usage: cli_test.sh SPRINGFIT SOURCE_DIR
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

# run: exact recovery with --json, the trace CSV and the result file; bad options.
expect_exit 0 "run paper json" "$sf" run "$src/examples/paper-iso-5x5.json" --strategy paper --seed 1 --threads 2 --json --trace "$tmp/trace.csv" -o "$tmp/result.json"
python3 - "$tmp/out" "$tmp/trace.csv" "$tmp/result.json" <<'PY' || fail "run --json content"
import csv, json, sys
j = json.load(open(sys.argv[1]))
for key in ["strategy", "seed", "exact", "hamming", "missing", "extra", "springs", "cost",
            "normalized_error", "generations", "evaluations", "wall_seconds"]:
    assert key in j, key
assert j["strategy"] == "paper" and j["seed"] == 1 and j["exact"] is True and j["hamming"] == 0, j
assert j["stop"] == "target_reached" and len(j["springs"]) == 72 and "trace" not in j
rows = list(csv.DictReader(open(sys.argv[2])))
assert len(rows) == j["generations"] + 1 and rows[-1]["missing"] == "0", rows[-1]
full = json.load(open(sys.argv[3]))
assert len(full["trace"]) == len(rows) and full["springs"] == j["springs"]
PY
expect_exit 2 "run unknown strategy" "$sf" run "$src/examples/paper-iso-5x5.json" --strategy annealing
grep -q -- "--strategy: unknown strategy 'annealing' (expected default, paper, direct, hybrid or continuous)" "$tmp/err" || fail "strategy error: $(cat "$tmp/err")"
expect_exit 64 "run population 1" "$sf" run "$src/examples/paper-iso-5x5.json" --population 1
expect_exit 2 "run invalid scene" "$sf" run "$src/tests/data/invalid-index.json"
# Ctrl-C: stops, still writes the best so far, exit 130.
"$sf" run "$src/examples/kidney-2d.json" --strategy paper --generations 100000 --threads 1 -q --json -o "$tmp/cancelled.json" >"$tmp/out" 2>"$tmp/err" &
pid=$!
sleep 1
kill -INT "$pid"
wait "$pid"
code=$?
[ "$code" -eq 130 ] || fail "run interrupted: exit $code, expected 130 ($(head -c 300 "$tmp/err"))"
python3 -c "import json; j=json.load(open('$tmp/cancelled.json')); assert j['stop'] == 'cancelled' and j['generations'] < 100000 and len(j['trace']) == j['generations'] + 1" || fail "interrupted run writes its result"

# run --strategy direct: topology and stiffness of stiff-2d (1e-4..1e4) from one solve.
expect_exit 0 "run direct" "$sf" run "$src/examples/stiff-2d.json" --strategy direct --json -o "$tmp/direct.json"
python3 - "$tmp/out" "$src/examples/stiff-2d.json" <<'PY' || fail "run direct content"
import json, sys
r = json.load(open(sys.argv[1]))
scene = json.load(open(sys.argv[2]))
assert r["strategy"] == "direct" and r["exact"] is True and r["stop"] == "target_reached", r["stop"]
truth = {tuple(p): k for p, k in zip(scene["reference"]["springs"], scene["reference"]["stiffness"])}
assert len(r["stiffness"]) == len(r["springs"]) == 72
worst = max(abs(k - truth[tuple(p)]) / truth[tuple(p)] for p, k in zip(r["springs"], r["stiffness"]))
assert worst < 1e-6, worst
assert r["direct"]["force_residual"] < 1e-9 and r["direct"]["unseen"] == [], r["direct"]
PY
expect_exit 0 "render direct" "$sf" render "$tmp/direct.json" -o "$tmp/direct.svg"
grep -q "exact recovery; 72 springs; E 0<" "$tmp/direct.svg" || fail "render draws a direct result with its own stiffness (error 0, not that of stiffness 1)"
# Per-spring stiffness as line width: 5 widths by log stiffness over 1e-4 .. 1e4, the same bins
# in both panels (the reference's stiffness is the result's here), and the range in the heading.
python3 - "$tmp/direct.svg" "$tmp/direct.json" <<'PY' || fail "render line widths"
import json, math, sys, xml.etree.ElementTree as ET
ns = "{http://www.w3.org/2000/svg}"
r = json.load(open(sys.argv[2]))
root = ET.parse(sys.argv[1]).getroot()
groups = [g for g in root.iter(ns + "g") if g.get("class") == "spring"]
lo, hi = min(r["stiffness"]), max(r["stiffness"])
want = [f"k{min(4, int(5 * math.log(k / lo) / math.log(hi / lo)))}" for k in r["stiffness"]]
cases = len(r["scene_definition"]["load_cases"])
assert len(groups) == 2 * cases, len(groups)
identified = [[l.get("class") for l in g.iter(ns + "line")] for g in groups[1::2]]
assert all(c == want for c in identified), (identified[0][:8], want[:8])
assert set(want) == {"k0", "k1", "k2", "k3", "k4"}, set(want)
texts = "".join(t.text or "" for t in root.iter(ns + "text"))
assert "width: stiffness 0.0001 to 1e+04 (log)" in texts, texts[:300]
PY

# run -o: a result file that cannot be written is said before the run, not after it.
expect_exit 1 "run -o unwritable" "$sf" run "$src/examples/paper-iso-5x5.json" --strategy paper -o "$tmp/no-such-dir/r.json"
grep -q "cannot write the result file $tmp/no-such-dir/r.json" "$tmp/err" || fail "run -o unwritable: $(cat "$tmp/err")"
[ -s "$tmp/out" ] && fail "run -o unwritable ran the search: $(head -c 200 "$tmp/out")"
grep -q "running" "$tmp/err" && fail "run -o unwritable started the run: $(cat "$tmp/err")"

# default on a scene whose reference springs differ in stiffness runs direct (hybrid spent 22 s
# and missed 20 springs on stiff-2d), and check says so and why.
expect_exit 0 "check stiff default" "$sf" check "$src/examples/stiff-2d.json"
grep -q "strategy default (direct here), identifies the topology and each spring's stiffness" "$tmp/out" \
  || fail "check stiff-2d: $(grep search "$tmp/out")"
grep -q "why direct: the reference's springs differ in stiffness" "$tmp/out" || fail "check says why: $(cat "$tmp/out")"
expect_exit 0 "check iso default" "$sf" check "$src/examples/paper-iso-5x5.json"
grep -q "strategy default (hybrid here), identifies the topology (every spring at the training stiffness)" "$tmp/out" \
  || fail "check iso: $(grep search "$tmp/out")"
expect_exit 0 "run stiff default" "$sf" run "$src/examples/stiff-2d.json" --json
python3 -c "import json; r=json.load(open('$tmp/out')); assert r['exact'] is True and 'direct' in r and r['identify'] == 'topology_and_stiffness', (r['exact'], r['identify'])" \
  || fail "default on stiff-2d: $(head -c 300 "$tmp/out")"

# example --noise: a positions reference; direct on it carries confidences.
expect_exit 0 "example noise" "$sf" example paper-aniso-5x5 --noise 0.001 --noise-seed 3 -o "$tmp/noisy.json"
expect_exit 0 "example clean" "$sf" example paper-aniso-5x5 -o "$tmp/clean.json"
expect_exit 0 "run direct noisy" "$sf" run "$tmp/noisy.json" --strategy direct --json
python3 - "$tmp/noisy.json" "$tmp/out" "$tmp/clean.json" <<'PY' || fail "noisy example and its direct result"
import json, sys
scene = json.load(open(sys.argv[1]))
r = json.load(open(sys.argv[2]))
clean = json.load(open(sys.argv[3]))
assert scene["reference"]["type"] == "positions" and len(scene["reference"]["positions"]) == 7
assert scene["name"] == "paper-aniso-5x5-noise0.001-s3", scene["name"]
assert r["exact"] is None  # a positions reference has no known topology
# ... but it is the clean scene's: 0.1% noise leaves the force balance readable (bench/RESULTS.md).
found = {tuple(sorted(p)) for p in r["springs"]}
assert found == {tuple(sorted(p)) for p in clean["reference"]["springs"]} and len(found) == 56, (len(found), len(clean["reference"]["springs"]))
assert len(r["confidence"]) == len(r["springs"]) and min(r["confidence"]) > 0, r["confidence"]
PY
expect_exit 64 "example noise out of range" "$sf" example paper-iso-5x5 --noise 2

# --identify topology: every spring at the training stiffness; a GA cannot identify stiffness.
expect_exit 0 "run direct topology" "$sf" run "$tmp/noisy.json" --strategy direct --identify topology --json
python3 - "$tmp/out" <<'PY' || fail "direct topology only"
import json, sys
r = json.load(open(sys.argv[1]))
assert r["identify"] == "topology" and set(r["stiffness"]) == {1.0}, (r["identify"], set(r["stiffness"]))
assert r["direct"]["topology_threshold"] > 0 and r["direct"]["added_to_carry"] == [] and not r["mechanism"]
PY
expect_exit 2 "identify stiffness with a GA" "$sf" run "$tmp/noisy.json" --strategy hybrid --identify topology_and_stiffness
grep -q "search.identify: topology_and_stiffness needs strategy direct" "$tmp/err" || fail "names the field: $(cat "$tmp/err")"
# default asked for stiffness runs direct.
expect_exit 0 "default identifies stiffness" "$sf" run "$tmp/noisy.json" --identify topology_and_stiffness --json
python3 -c "import json; r=json.load(open('$tmp/out')); assert r['identify'] == 'topology_and_stiffness' and 'direct' in r, r['identify']" \
  || fail "default with topology_and_stiffness: $(head -c 300 "$tmp/out")"
expect_exit 2 "identify unknown" "$sf" run "$tmp/noisy.json" --identify shape
grep -q -- "--identify: unknown value 'shape'" "$tmp/err" || fail "names the option: $(cat "$tmp/err")"

# render and plot: SVG files from result files; the wrong springs are drawn one line each.
expect_exit 0 "render exact" "$sf" render "$tmp/result.json" -o "$tmp/exact.svg"
"$sf" run "$src/examples/paper-iso-5x5.json" --strategy paper --generations 5 -q -o "$tmp/short.json" >/dev/null
expect_exit 0 "render short" "$sf" render "$tmp/short.json" --case 1 -o "$tmp/short.svg"
expect_exit 0 "plot" "$sf" plot "$tmp/result.json" "$tmp/short.json" -o "$tmp/plot.svg" --title "iso"
# plot --x generations: the paper's Figure 2 axis (5 generations: decades 1 and 10); render
# and plot write SVG only, and say so for another name (nothing written).
expect_exit 0 "plot generations" "$sf" plot "$tmp/short.json" --x generations -o "$tmp/gen.svg"
grep -q 'Normalized error against generations' "$tmp/gen.svg" || fail "plot --x generations: no title"
grep -q 'y="442.00" text-anchor="middle">10</text>' "$tmp/gen.svg" || fail "plot --x generations: no decade 10 on the x axis"
grep -q 'y="442.00" text-anchor="middle">1e-' "$tmp/gen.svg" && fail "plot --x generations drew seconds"
expect_exit 64 "plot png" "$sf" plot "$tmp/short.json" -o "$tmp/plot.png"
grep -q "does not end in .svg" "$tmp/err" || fail "plot png: $(cat "$tmp/err")"
[ -e "$tmp/plot.png" ] && fail "plot wrote a .png file"
expect_exit 64 "render pdf" "$sf" render "$tmp/short.json" -o "$tmp/t.pdf"
[ -e "$tmp/t.pdf" ] && fail "render wrote a .pdf file"
python3 - "$tmp/exact.svg" "$tmp/short.svg" "$tmp/short.json" "$tmp/plot.svg" <<'PY' || fail "render/plot content"
import json, sys, xml.etree.ElementTree as ET
ns = "{http://www.w3.org/2000/svg}"
def lines(path, cls):  # shapes of a class, the legend sample excluded
    return sum(1 for e in ET.parse(path).iter() if e.get("class") == cls) - 1
assert lines(sys.argv[1], "missing") == 0 and lines(sys.argv[1], "extra") == 0
short = json.load(open(sys.argv[3]))
assert short["hamming"] > 0, short["hamming"]
assert lines(sys.argv[2], "missing") == len(short["missing"]), "one load case: one line per missing spring"
assert lines(sys.argv[2], "extra") == len(short["extra"])
plot = ET.parse(sys.argv[4])
assert sum(1 for e in plot.iter(ns + "polyline")) == 2
assert sum(1 for e in plot.iter(ns + "circle") if e.get("class") == "exact0") == 1  # the exact run's marker
PY
# --rest: the two topologies at rest, one pair of panels, no load case drawn; --node-numbers
# writes every node's index in each panel.
expect_exit 0 "render --rest" "$sf" render "$tmp/short.json" --rest --node-numbers -o "$tmp/rest.svg"
python3 - "$tmp/rest.svg" "$tmp/short.json" <<'PY' || fail "render --rest content"
import json, sys, xml.etree.ElementTree as ET
ns = "{http://www.w3.org/2000/svg}"
root = ET.parse(sys.argv[1]).getroot()
short = json.load(open(sys.argv[2]))
n = len(short["scene_definition"]["nodes"])
of = lambda cls: [e for e in root.iter() if e.get("class") == cls]
assert len([e for e in of("panel") if e.tag == ns + "rect"]) == 2
numbers = [t.text for t in of("number")]
assert sorted(numbers) == sorted([str(i) for i in range(n)] * 2), numbers[:10]
assert len(of("missing")) - 1 == len(short["missing"]) and len(of("extra")) - 1 == len(short["extra"])
assert not of("rest") and not of("force") and not of("fixed"), "a load case drawn at rest"
texts = "".join(t.text or "" for t in root.iter(ns + "text"))
assert "identified topology, at rest" in texts and "displacements" not in texts, texts[:300]
PY
expect_exit 64 "render --rest --case" "$sf" render "$tmp/short.json" --rest --case 0 -o "$tmp/x.svg"
expect_exit 2 "render missing file" "$sf" render "$tmp/nope.json" -o "$tmp/x.svg"
expect_exit 2 "render load case out of range" "$sf" render "$tmp/short.json" --case 7 -o "$tmp/x.svg"
grep -q "load case 7 out of range" "$tmp/err" || fail "render names the load case: $(cat "$tmp/err")"
"$sf" run "$src/examples/paper-iso-5x5.json" -q --json >"$tmp/stdout-result.json"
expect_exit 2 "render without a scene" "$sf" render "$tmp/stdout-result.json" -o "$tmp/x.svg"
grep -q -- "--scene" "$tmp/err" || fail "render asks for --scene: $(cat "$tmp/err")"
expect_exit 0 "render with --scene" "$sf" render "$tmp/stdout-result.json" --scene "$src/examples/paper-iso-5x5.json" -o "$tmp/x.svg"
expect_exit 2 "plot without a trace" "$sf" plot "$tmp/stdout-result.json" -o "$tmp/x.svg"
expect_exit 64 "render without -o" "$sf" render "$tmp/short.json"

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
grep -q "^unseen loads:      [0-9]* held-out probes on [0-9]* supports, never fitted: median E .*; baseline " "$tmp/out" || fail "run prints the held-out E: $(cat "$tmp/out")"
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
expect_exit 12 "run fem kidney doubtful" "$sf" run "$src/examples/fem-kidney-2d.json" -q
grep -q "^WARNING: *the certificate: a load on your supports can move the model by up to [0-9.]* times" "$tmp/out" || fail "the doubt is not said: $(grep -E 'verdict|WARNING' "$tmp/out")"
# and where to read what changes it (a new user's trial found no hint).
grep -A1 "^WARNING:" "$tmp/out" | tail -1 | grep -q '^what to try: *proto/RUN.md, "What to try"' || fail "no hint after the doubts: $(grep -A1 -E 'WARNING' "$tmp/out" | tail -2)"
grep -q '^### What to try$' "$src/proto/RUN.md" || fail "proto/RUN.md has no section What to try"
expect_exit 2 "bad probes" "$sf" run "$src/examples/fem-plate-5x5.json" --probes many
grep -q -- "--probes: must be \"auto\", \"none\" or a count from 1 to 20000, got 'many'" "$tmp/err" || fail "probes names the value: $(cat "$tmp/err")"

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

finish cli
