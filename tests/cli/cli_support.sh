# shellcheck shell=bash disable=SC2154  # (sf and src are the sourcing script's)
# The CLI test scripts' shared part beyond tests/checks.sh, which it sources (after sf=... and
# src=...): the result files more than one script reads.
source "$(dirname "${BASH_SOURCE[0]}")/../checks.sh"

# paper_result FILE: the paper strategy's exact recovery of paper-iso-5x5 (seed 1, 2 threads)
# written to FILE, trace included: the result cli_run_test.sh's "run paper json" checks and
# writes to its $tmp/result.json.
paper_result() {
  "$sf" run "$src/examples/paper-iso-5x5.json" --strategy paper --seed 1 --threads 2 -q -o "$1" >/dev/null 2>&1 \
    || fail "the paper strategy's result $1, which later checks read"
}
