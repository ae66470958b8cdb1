#!/usr/bin/env bash
# Starts springfitd on loopback with a fresh database and runs bench/daemon_bench against it.
# Usage: bench/daemon_bench.sh [BUILD_DIR]   (from the repository root; default build)
set -euo pipefail
build=${1:-build}
run=$(mktemp -d)
"$build/server/springfitd" --listen 127.0.0.1:0 --db "$run/bench.db" --port-file "$run/port" --workers 2 \
  --log-level warn --max-connections 1000 &
daemon=$!
trap 'kill -TERM "$daemon"; wait "$daemon" || true; rm -rf "$run"' EXIT
for _ in $(seq 100); do [ -s "$run/port" ] && break; sleep 0.05; done
server="127.0.0.1:$(cat "$run/port")"
"$build/bench/daemon_bench" --server "$server" --get --clients 50 --seconds 5
"$build/bench/daemon_bench" --server "$server" --overhead examples/kidney-2d.json --strategy paper --generations 100 --threads 2 --repeats 5
"$build/bench/daemon_bench" --server "$server" --overhead examples/paper-aniso-5x5.json --strategy paper --generations 1000 --threads 2 --repeats 10
