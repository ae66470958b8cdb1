#!/usr/bin/env bash
# The README's main job: start springfitd on the embedded SQLite default (springfit.db in
# the working directory), submit an example scene, watch it to the end, print its result,
# stop the daemon. Also a template for a pipeline step.
# Usage: scripts/main-job.sh [SCENE]   (default examples/paper-iso-5x5.json)
set -euo pipefail
cd "$(dirname "$0")/.."
scene=${1:-examples/paper-iso-5x5.json}
run_dir=$(mktemp -d)
build/server/springfitd --listen 127.0.0.1:0 --port-file "$run_dir/port" --log-level warn &
daemon=$!
trap 'kill -TERM "$daemon" 2>/dev/null; wait "$daemon" 2>/dev/null; rm -rf "$run_dir"' EXIT
for _ in $(seq 100); do [ -s "$run_dir/port" ] && break; sleep 0.05; done
export SPRINGFIT_SERVER="127.0.0.1:$(cat "$run_dir/port")"
echo "springfitd on $SPRINGFIT_SERVER, database $(pwd)/springfit.db"
job=$(build/client/springfit submit "$scene" --label main-job)
build/client/springfit watch "$job" >/dev/null
build/client/springfit result "$job"
