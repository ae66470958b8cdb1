#!/usr/bin/env bash
# springfitd end to end, on loopback: submit/watch/result through the CLI, and jobs that
# survive kill -9 and a graceful stop, resuming to exactly the result and trace of an
# uninterrupted local run with the same seed.
# Usage: daemon_test.sh SPRINGFITD SPRINGFIT SOURCE_DIR
set -u
daemon_bin=$1
sf=$2
src=$3
tmp=$(mktemp -d)
pid=""
cleanup() { [ -n "$pid" ] && kill -9 "$pid" 2>/dev/null; rm -rf "$tmp"; }
trap cleanup EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

start_daemon() {  # extra flags...
  rm -f "$tmp/port"
  "$daemon_bin" --listen 127.0.0.1:0 --db "$tmp/jobs.db" --port-file "$tmp/port" --workers 2 \
    --checkpoint-seconds 0.2 "$@" >>"$tmp/daemon.log" 2>&1 &
  pid=$!
  for _ in $(seq 100); do [ -s "$tmp/port" ] && break; sleep 0.05; done
  [ -s "$tmp/port" ] || { fail "daemon did not start: $(tail -3 "$tmp/daemon.log")"; exit 1; }
  export SPRINGFIT_SERVER=127.0.0.1:$(cat "$tmp/port")
}

json_field() {  # file field
  python3 -c "import json,sys; v=json.load(open(sys.argv[1]))[sys.argv[2]]; print('' if v is None else v)" "$1" "$2"
}

# Waits (at most 30 s) until job $1 has a checkpoint at generation >= $2.
wait_for_checkpoint() {
  for _ in $(seq 300); do
    "$sf" status "$1" --json >"$tmp/status.json" 2>/dev/null || true
    local c
    c=$(json_field "$tmp/status.json" checkpoint_generation 2>/dev/null)
    [ -n "$c" ] && [ "$c" -ge "$2" ] && return 0
    sleep 0.1
  done
  fail "job $1 reached no checkpoint at generation $2"
  return 1
}

# The exit codes a finished job's result may give: its verdict's (usable 0, unusable 10, unmet
# request 11, doubtful 12), the same as `springfit run`'s of the same scene.
verdict_code() { case $1 in 0|10|11|12) return 0 ;; *) return 1 ;; esac; }
# Watches job $1 to its end; its exit code in $watched.
watch_job() {
  "$sf" watch "$1" -q >/dev/null
  watched=$?
  verdict_code "$watched" || fail "watch $1: exit $watched"
}

# The daemon's result and trace of job $1 equal a local run of scene $2 with the flags after it,
# wall times and cache hits aside (a job resumed from a checkpoint starts with an empty fitness
# cache, which changes only how many evaluations it answers from the cache).
expect_same_as_local() {
  local id=$1 scene=$2; shift 2
  "$sf" result "$id" --json >"$tmp/daemon.json"
  local result_code=$?
  verdict_code "$result_code" || fail "result $id: exit $result_code"
  "$sf" trace "$id" --csv | cut -d, -f1,3,5- >"$tmp/daemon.csv"
  "$sf" run "$scene" "$@" --json -q --threads 1 --trace "$tmp/local_full.csv" >"$tmp/local.json"
  local local_code=$?
  # One verdict: watch, result and a local run exit alike.
  [ "$result_code" = "$local_code" ] || fail "job $id: result exits $result_code, a local run $local_code"
  [ "$watched" = "$local_code" ] || fail "job $id: watch exited $watched, a local run $local_code"
  cut -d, -f1,3,5- "$tmp/local_full.csv" >"$tmp/local.csv"  # wall time and cache hits aside
  cmp -s "$tmp/daemon.csv" "$tmp/local.csv" || fail "job $id: trace differs from an uninterrupted local run"
  python3 - "$tmp/daemon.json" "$tmp/local.json" <<'PY' || fail "job $id: result differs from an uninterrupted local run"
import json, sys
daemon, local = (json.load(open(p)) for p in sys.argv[1:])
diff = [k for k in local if k not in ("wall_seconds", "threads", "cache_hits") and daemon.get(k) != local[k]]
if diff:
    print("differing fields:", diff)
    sys.exit(1)
PY
}

kidney="$src/examples/kidney-2d.json"
run_flags=(--strategy paper --generations 60)

start_daemon
# A finished job, to find intact after the crash.
"$sf" submit "$src/examples/paper-iso-5x5.json" --label kept --wait >"$tmp/kept.txt" || fail "submit --wait: exit $?"
grep -q "recovered exactly" "$tmp/kept.txt" || fail "submit --wait prints the result: $(cat "$tmp/kept.txt")"
kept_id=$("$sf" list --label kept --json | python3 -c "import json,sys; print(json.load(sys.stdin)['jobs'][0]['job_id'])")
"$sf" result "$kept_id" --json >"$tmp/kept_before.json"

# kill -9 in the middle of a job; the restart resumes it from its checkpoint.
id=$("$sf" submit "$kidney" "${run_flags[@]}" --seed 5 2>/dev/null) || fail "submit"
wait_for_checkpoint "$id" 5
kill -9 "$pid"
wait "$pid" 2>/dev/null
start_daemon
# (The resume is logged just after the daemon listens: wait for the line, bounded.)
for _ in $(seq 100); do grep -q "resumed from its checkpoint" "$tmp/daemon.log" && break; sleep 0.1; done
grep -q "resumed from its checkpoint" "$tmp/daemon.log" || fail "the restart did not resume job $id from a checkpoint"
watch_job "$id"
expect_same_as_local "$id" "$kidney" "${run_flags[@]}" --seed 5
"$sf" result "$kept_id" --json >"$tmp/kept_after.json"
cmp -s "$tmp/kept_before.json" "$tmp/kept_after.json" || fail "a finished job changed across the crash"

# SIGTERM with a job running: the daemon checkpoints it, exits, and the next start finishes it.
id2=$("$sf" submit "$kidney" "${run_flags[@]}" --seed 6 2>/dev/null) || fail "submit"
wait_for_checkpoint "$id2" 3
kill -TERM "$pid"
for _ in $(seq 200); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
if kill -0 "$pid" 2>/dev/null; then fail "the daemon did not stop within 20 s of SIGTERM"; fi
wait "$pid"
[ $? -eq 0 ] || fail "graceful stop: non-zero exit"
grep -q "interrupted by the shutdown" "$tmp/daemon.log" || fail "job $id2 was not checkpointed at the shutdown"
start_daemon
"$sf" status "$id2" --json >"$tmp/s2.json"
state=$(json_field "$tmp/s2.json" state)
[ "$state" = running ] || [ "$state" = queued ] || [ "$state" = succeeded ] || fail "job $id2 after the restart: $state"
watch_job "$id2"
expect_same_as_local "$id2" "$kidney" "${run_flags[@]}" --seed 6

# result -o carries the trace; exit codes of a cancelled job and of a job not found.
"$sf" result "$id2" -o "$tmp/r.json" >/dev/null
verdict_code $? || fail "result -o"
python3 -c "import json,sys; r=json.load(open(sys.argv[1])); assert len(r['trace'])==r['generations']+1" "$tmp/r.json" \
  || fail "result -o: the trace has one row per generation"
# render and plot by job id; result -o carries the scene, so its file renders offline too.
"$sf" render "$id2" -o "$tmp/r-id.svg" || fail "render by job id"
"$sf" render "$tmp/r.json" -o "$tmp/r-file.svg" || fail "render the result file"
cmp -s <(sed 1,2d "$tmp/r-id.svg" | grep -v '^<text class="title"') <(sed 1,2d "$tmp/r-file.svg" | grep -v '^<text class="title"') \
  || fail "render by id and of result -o draw the same figure"
"$sf" plot "$id2" "$tmp/r.json" -o "$tmp/p.svg" || fail "plot by job id"
# export by job id writes the model of the result file, byte for byte.
"$sf" export "$id2" -o "$tmp/m-id.json" >/dev/null || fail "export by job id"
"$sf" export "$tmp/r.json" -o "$tmp/m-file.json" >/dev/null || fail "export the result file"
cmp -s "$tmp/m-id.json" "$tmp/m-file.json" || fail "export by id and of result -o write the same model"
# A mesh with its loads: the client imports it and sends the scene; the job runs that scene.
gmsh "$src/examples/pipeline/inclusion.geo" -2 -o "$tmp/inclusion.msh" >/dev/null || fail "gmsh"
"$sf" import "$tmp/inclusion.msh" --loads "$src/examples/pipeline/inclusion-loads.json" -o "$tmp/inclusion.json" 2>/dev/null || fail "import"
id_mesh=$("$sf" submit "$tmp/inclusion.msh" --loads "$src/examples/pipeline/inclusion-loads.json" --max-springs 700 2>/dev/null) || fail "submit a mesh"
watch_job "$id_mesh"
"$sf" result "$id_mesh" -o "$tmp/mesh-result.json" >/dev/null
[ $? = "$watched" ] || fail "result of the mesh's job: another exit code than its watch's ($watched)"
python3 - "$tmp/mesh-result.json" "$tmp/inclusion.json" <<'PY' || fail "the job ran the imported scene"
import json, sys
r = json.load(open(sys.argv[1]))
scene = json.load(open(sys.argv[2]))
d = r["scene_definition"]
assert d["nodes"] == scene["nodes"] and d["reference"]["elements"] == scene["reference"]["elements"]
assert d["reference"]["element_materials"] == scene["reference"]["element_materials"]
assert [c["name"] for c in d["load_cases"]] == [c["name"] for c in scene["load_cases"]]
assert len(r["springs"]) <= 700
PY
"$sf" render 123456 -o "$tmp/none.svg" 2>/dev/null
[ $? -eq 4 ] || fail "render of an unknown job exits 4"
id3=$("$sf" submit "$kidney" --strategy paper --generations 100000 2>/dev/null)
"$sf" cancel "$id3" >/dev/null || fail "cancel"
"$sf" watch "$id3" -q >/dev/null
[ $? -eq 7 ] || fail "watch of a cancelled job exits 7"
"$sf" status 123456 >/dev/null 2>&1
[ $? -eq 4 ] || fail "status of an unknown job exits 4"

# An FEM reference through the daemon: the same result as a local run, with E and the baseline.
fem="$src/examples/fem-kidney-2d-nl.json"
fem_id=$("$sf" submit "$fem" --strategy paper --generations 5 --seed 3 2>/dev/null) || fail "submit fem"
watch_job "$fem_id"
expect_same_as_local "$fem_id" "$fem" --strategy paper --generations 5 --seed 3
python3 -c "import json,sys; r=json.load(open(sys.argv[1])); assert r['baseline']['recipe']=='van_gelder_1998' and r['rms_error']>0, r" \
  "$tmp/daemon.json" || fail "fem job result carries E and the baseline"

# The kidney at five times its loads, past small strain.
python3 - "$src/examples/fem-kidney-2d.json" "$tmp/kidney-large.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
for lc in s["load_cases"]:
    for t in lc.get("tractions", []):
        for key in ("total", "per_length"):
            if key in t:
                t[key] = [5.0 * x for x in t[key]]
json.dump(s, open(sys.argv[2], "w"))
PY
# One verdict (issue 33): what `run` says of a model, the daemon says too, with the same exit
# code. A useless model (direct on the FEM kidney past small strain: E above 1) is not
# "succeeded, exit 0".
"$sf" submit "$tmp/kidney-large.json" --strategy direct --label useless --wait >"$tmp/useless.txt" 2>&1
code=$?
[ $code -eq 10 ] || fail "submit --wait of a useless model: exit $code, expected 10 as run gives"
grep -q "^NO USABLE MODEL: " "$tmp/useless.txt" || fail "submit --wait of a useless model says why: $(head -5 "$tmp/useless.txt")"
useless_id=$("$sf" list --label useless --json | python3 -c "import json,sys; print(json.load(sys.stdin)['jobs'][0]['job_id'])")
grep -q "job $useless_id: no usable model: " "$tmp/daemon.log" || fail "the daemon's log names the useless model"
# An option the strategy that runs ignores is refused at the door, as run refuses it.
python3 - "$src/examples/fem-plate-5x5.json" "$tmp/plate-target.json" <<'PY'
import json, sys
scene = json.load(open(sys.argv[1]))
scene["search"] = {"target_normalized_error": 0.01}
json.dump(scene, open(sys.argv[2], "w"))
PY
"$sf" submit "$tmp/plate-target.json" >/dev/null 2>"$tmp/target.err"
code=$?
[ $code -eq 2 ] || fail "submit of a continuous scene with a genetic target: exit $code, expected 2"
grep -q "search.target_normalized_error: is read by the genetic search only" "$tmp/target.err" || fail "the refusal names the setting: $(cat "$tmp/target.err")"
# One vocabulary per strategy: a continuous job is shown by its fit's steps and E, never as
# generations with an ETA, and the job names the strategy that ran.
"$sf" submit "$src/examples/fem-plate-5x5.json" --label vocabulary --watch >/dev/null 2>"$tmp/vocabulary.err"
grep -q "^fit step [0-9]*  E " "$tmp/vocabulary.err" || fail "submit --watch of a continuous job does not show its fit steps: $(head -3 "$tmp/vocabulary.err")"
! grep -q "^gen \|ETA" "$tmp/vocabulary.err" || fail "a continuous job is shown as a genetic run: $(grep -m1 "^gen \|ETA" "$tmp/vocabulary.err")"
"$sf" list --label vocabulary --json | python3 -c "import json,sys; j=json.load(sys.stdin)['jobs'][0]; assert j['strategy']=='continuous', j['strategy']" \
  || fail "the job does not name the strategy that ran"
# info shows its limits one to a line, not as one raw JSON line.
"$sf" info >"$tmp/info.txt" || fail "info"
grep -q "^  max_nodes: *[0-9]" "$tmp/info.txt" || fail "info does not list its limits one to a line: $(cat "$tmp/info.txt")"
! grep -q "^limits: *{" "$tmp/info.txt" || fail "info prints its limits as raw JSON"
# The small-strain doubt reaches a pipeline through the daemon too: the same verdict and exit
# code as run's (12), and its WARNING line.
"$sf" submit "$tmp/kidney-large.json" --wait >"$tmp/large.txt" 2>&1
code=$?
[ $code -eq 12 ] || fail "submit --wait of a doubtful model: exit $code, expected 12"
grep -q "^WARNING: .*the linear reference is loaded past small strain" "$tmp/large.txt" || fail "submit --wait does not show the small-strain doubt: $(head -5 "$tmp/large.txt")"
# A spring budget no model meets: the model and a WARNING line, exit 11, listed as such.
"$sf" submit "$src/examples/fem-plate-5x5.json" --strategy continuous --max-springs 1 --label budget --wait >"$tmp/budget.txt" 2>&1
code=$?
[ $code -eq 11 ] || fail "submit --wait with an unmet spring budget: exit $code, expected 11"
grep -q "^WARNING: *spring budget not met" "$tmp/budget.txt" || fail "no WARNING line for the unmet budget: $(head -5 "$tmp/budget.txt")"
"$sf" run "$src/examples/fem-plate-5x5.json" --strategy continuous --max-springs 1 -q >/dev/null
[ $? -eq 11 ] || fail "run with an unmet spring budget does not exit 11"
"$sf" list --label budget >"$tmp/budget-list.txt"
grep -q " succeeded  unmet_request " "$tmp/budget-list.txt" || fail "list does not show the verdict: $(cat "$tmp/budget-list.txt")"
budget_id=$("$sf" list --label budget --json | python3 -c "import json,sys; print(json.load(sys.stdin)['jobs'][0]['job_id'])")
"$sf" watch "$budget_id" -q >/dev/null
[ $? -eq 11 ] || fail "watch of the unmet budget's job does not exit 11"
"$sf" result "$budget_id" >/dev/null
[ $? -eq 11 ] || fail "result of the unmet budget's job does not exit 11"
"$sf" status "$budget_id" | grep -q "^verdict: *unmet_request: " || fail "status does not show the verdict"

kill -TERM "$pid"
wait "$pid"
pid=""
if [ "$failures" -ne 0 ]; then
  echo "--- daemon log"; tail -30 "$tmp/daemon.log"
  echo "$failures failure(s)"
  exit 1
fi
echo "daemon tests passed"
