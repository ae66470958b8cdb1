# The end-to-end test scripts' shared part (sourced): a scratch directory removed on exit,
# failures counted, commands run with their exit code checked, the verdict.
#   source "$(dirname "$0")/../checks.sh"   # after sf=... and src=...
#   expect_exit 0 "what it checks" "$sf" run ...   # stdout in $tmp/out, stderr in $tmp/err
#   finish NAME                                   # prints the verdict; the script's status
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }

expect_exit() {  # expected_code description command...
  local want=$1 what=$2
  shift 2
  "$@" >"$tmp/out" 2>"$tmp/err"
  local got=$?
  [ "$got" -eq "$want" ] || fail "$what: exit $got, expected $want ($(head -c 300 "$tmp/err"))"
}

finish() {  # name
  if [ "$failures" -eq 0 ]; then echo "$1: all checks passed"; else echo "$1: $failures failed"; fi
  [ "$failures" -eq 0 ]
}

# meshio (Debian's python3-meshio) is installed for Debian's python3, which may not be the
# first python3 on the PATH.
debian_python=/usr/bin/python3
need_meshio() {
  "$debian_python" -c "import meshio" 2>/dev/null && return 0
  echo "FAIL: $debian_python cannot import meshio: run scripts/install-deps.sh"
  exit 1
}
