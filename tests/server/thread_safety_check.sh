#!/usr/bin/env bash
# Compiles the daemon's sources (server/) with clang's thread-safety analysis as errors: a
# member declared SF_GUARDED_BY(m) (server/mutex.h) touched without m held, a function
# declared SF_REQUIRES(m) called without it, fails the check. Syntax only: nothing is built.
#   thread_safety_check.sh BUILD_DIR   (the build's compile_commands.json gives the flags)
set -euo pipefail
build=$1
commands="$build/compile_commands.json"
[ -f "$commands" ] || { echo "FAIL: no $commands (CMAKE_EXPORT_COMPILE_COMMANDS)"; exit 1; }
command -v clang++ >/dev/null || { echo "FAIL: no clang++: run scripts/install-deps.sh"; exit 1; }

# One clang command per source of springfit_server and springfitd (unity batches included):
# GCC's command with its compiler, output and warnings replaced.
mapfile -t lines < <(python3 - "$commands" <<'PY'
import json, shlex, sys
for entry in json.load(open(sys.argv[1])):
    source = entry["file"]
    if "/server/" not in source or "/tests/" in source:
        continue
    args = shlex.split(entry["command"])[1:]
    kept, skip = [], False
    for a in args:
        if skip:
            skip = False
            continue
        if a == "-o":
            skip = True
            continue
        if a in ("-c", source) or a.startswith("-W"):
            continue
        kept.append(a)
    print(shlex.join([entry["directory"], *kept, source]))
PY
)
[ ${#lines[@]} -gt 0 ] || { echo "FAIL: no server sources in $commands"; exit 1; }

failures=0
for line in "${lines[@]}"; do
  eval "set -- $line"
  dir=$1
  shift
  if ! (cd "$dir" && clang++ -fsyntax-only -Wno-everything -Wthread-safety -Werror=thread-safety "$@"); then
    echo "FAIL: thread-safety analysis: ${*: -1}"
    failures=$((failures + 1))
  fi
done
echo "thread_safety_check: ${#lines[@]} sources, $failures failed"
[ "$failures" -eq 0 ]
