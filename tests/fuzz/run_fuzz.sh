#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (a second build tree, instrumented with
# AddressSanitizer and UndefinedBehaviorSanitizer) and runs each for a bounded time from its
# seed corpus. Any crash, sanitizer report, leak, timeout or failed check fails the test;
# libFuzzer writes the offending input to the build tree and its path is printed.
#
# The unit tests under the sanitizers would double this test's time (the engine's instrumented
# build and run: 4 minutes on two cores; the formats' 2), more than the test command's budget
# allows: SPRINGFIT_SANITIZED_TESTS="engine_tests proto_tests" runs them in the same
# instrumented tree (a sanitizer report fails the test too: UBSan does not
# recover), and the README's sanitizer build runs every test under GCC's sanitizers. What the
# fuzz targets reach is instrumented here, and that alone is built: the message framer, the
# scene codec and the engine's preparation of a scene (validation, candidates, equilibria,
# rigidity, FEM), the libraries springfit_scene_format and springfit_engine_problem.
#
# Reproducible: a fixed seed and a fixed number of inputs per target (SPRINGFIT_FUZZ_RUNS
# scales them), so every machine tries the same inputs; a time bound stops a slow machine.
# For a longer local campaign: SPRINGFIT_FUZZ_SEED=0 (a new seed each run) and a larger
# SPRINGFIT_FUZZ_RUNS or SPRINGFIT_FUZZ_SECONDS.
#
# usage: run_fuzz.sh SOURCE_DIR FUZZ_BUILD_DIR
set -euo pipefail
src=$1
build=$2
seconds=${SPRINGFIT_FUZZ_SECONDS:-60}
runs_scale=${SPRINGFIT_FUZZ_RUNS:-1}

sanitized_tests=${SPRINGFIT_SANITIZED_TESTS:-}

# -O1, as libFuzzer's documentation builds its targets: a third less compile time than -O2
# for the same coverage. Line tables only, not full debug information: sanitizer reports still
# name the file and line.
CXX=clang++ cmake -S "$src" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSPRINGFIT_FUZZ=ON \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -gline-tables-only -DNDEBUG" \
  -DSPRINGFIT_BUILD_TESTS=ON -DSPRINGFIT_BUILD_BENCHMARKS=OFF >"$build.configure.log" 2>&1 ||
  { cat "$build.configure.log"; exit 1; }
# shellcheck disable=SC2086  # the list of test binaries is split on purpose
cmake --build "$build" -j2 --target framer_fuzz scene_fuzz $sanitized_tests >"$build.build.log" 2>&1 ||
  { tail -50 "$build.build.log"; exit 1; }

# A libFuzzer dictionary of the scene format's keys and enumerated values, from the schema,
# so that mutations produce scenes that get past the unknown-field check.
scene_dict="$build/scene.dict"
python3 - "$src/proto/scene.schema.json" >"$scene_dict" <<'PY'
import json, sys
words = set()
def walk(node):
    if isinstance(node, dict):
        words.update(node.get("properties", {}).keys())
        words.update(v for v in node.get("enum", []) if isinstance(v, str))
        for value in node.values():
            walk(value)
    elif isinstance(node, list):
        for value in node:
            walk(value)
walk(json.load(open(sys.argv[1])))
for word in sorted(words):
    print(json.dumps(json.dumps(word)))
PY

run() {
  local target=$1
  local runs=$(( $2 * runs_scale ))
  local options=$3
  shift 3
  local work="$build/run-$target"
  rm -rf "$work"
  mkdir -p "$work/corpus"
  cp "$@" "$work/corpus/"
  echo "== $target: $runs inputs (at most ${seconds}s) from $(ls "$work/corpus" | wc -l) seeds"
  # -timeout: one input taking over 10 s is a hang; -rss_limit_mb bounds memory per input;
  # -max_len holds the largest example scene whole.
  # -seed: the same mutations on every run, so a CI failure reproduces (SPRINGFIT_FUZZ_SEED=0:
  # a new seed each run, for longer local campaigns).
  (cd "$work" && "$build/tests/fuzz/$target" -runs="$runs" -max_total_time="$seconds" -timeout=10 -seed="${SPRINGFIT_FUZZ_SEED:-1}" \
     -rss_limit_mb=2048 -max_len=16384 -print_final_stats=1 $options corpus 2>"$work/log") || {
    tail -60 "$work/log"
    echo "$target failed; the input is in $work (crash-*, timeout-*, leak-*, oom-*)"
    exit 1
  }
  grep -E '^stat::(number_of_executed_units|new_units_added)' "$work/log" || true
}

# The unit tests under AddressSanitizer and UndefinedBehaviorSanitizer (engine_tests, when
# asked for, but for the seven longest (whole searches repeated to compare traces, every example prepared, whole continuous
# runs on the kidney and the plate: 80 s and 8 s instrumented; the Release run covers them, and
# their code paths run instrumented in the other tests).
slow="Cost.ReferenceTopologyCostsExactlyZeroAndEverySingleFlipCostsMore:Search.ResumingFromASnapshot*"
slow="$slow:Search.SameTraceAndResultWithOneOrTwoThreads:Search.ScalingTheSceneLeavesTheSearchUnchanged"
slow="$slow:Examples.EveryExampleBuildsWithAConvergedReference"
slow="$slow:ContinuousStrategy.ReturnsOnlyAModelTheStandardEvaluationConfirms"
slow="$slow:ContinuousStrategy.BeatsTheBaselineOnTheFemPlate"
# Each suite in two gtest shards at once (the tests are computations, independent of each
# other): the instrumented run takes half the wall time on two cores.
for tests in $sanitized_tests; do
  echo "== $tests under ASan and UBSan (2 shards)"
  pids=()
  for shard in 0 1; do
    # (20 of the numerics stress test's 120 scenes: 40 s instrumented for all of them)
    SPRINGFIT_STRESS_SCENES=20 GTEST_TOTAL_SHARDS=2 GTEST_SHARD_INDEX=$shard \
      "$build/tests/$tests" --gtest_brief=1 \
      --gtest_filter="-$slow" >"$build/$tests.$shard.log" 2>&1 &
    pids+=($!)
  done
  for shard in 0 1; do
    wait "${pids[$shard]}" || {
      tail -60 "$build/$tests.$shard.log"
      echo "$tests failed under the sanitizers (log: $build/$tests.$shard.log)"
      exit 1
    }
    tail -1 "$build/$tests.$shard.log"
  done
done

# The two targets at once, one per core (each is one process); each prints when it ends, and
# either failing fails the test.
run framer_fuzz 120000 "" "$src"/tests/fuzz/corpus/framer/* >"$build/framer_fuzz.out" 2>&1 &
framer=$!
run scene_fuzz 30000 "-dict=$scene_dict" "$src"/examples/*.json "$src"/tests/data/*.json \
  >"$build/scene_fuzz.out" 2>&1 &
scene=$!
status=0
wait $framer || status=1
cat "$build/framer_fuzz.out"
wait $scene || status=1
cat "$build/scene_fuzz.out"
exit $status
