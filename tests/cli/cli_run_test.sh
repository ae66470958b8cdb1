#!/usr/bin/env bash
# End-to-end checks of the springfit program: run with each strategy and its options (exact
# recovery, the trace and result files, Ctrl-C, direct's stiffness and confidences, the default
# strategy and why), outputs and exit codes.
# Usage: cli_run_test.sh SPRINGFIT SOURCE_DIR
set -u
sf=$1
src=$2
source "$(dirname "$0")/../checks.sh"

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

finish cli_run
