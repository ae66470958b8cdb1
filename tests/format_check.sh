#!/usr/bin/env bash
# The tree is formatted as .clang-format says (Debian 12's clang-format 14, from
# scripts/install-deps.sh): every tracked C++ source and header.
# Usage: format_check.sh SOURCE_DIR
set -u
cd "$1" || exit 1
command -v clang-format >/dev/null || { echo "clang-format not found: run scripts/install-deps.sh"; exit 1; }
mapfile -t files < <(git ls-files '*.cpp' '*.h')
[ "${#files[@]}" -gt 0 ] || { echo "no C++ files found under $1 (not a git checkout?)"; exit 1; }
if clang-format --dry-run -Werror "${files[@]}" 2>"${TMPDIR:-/tmp}/format_check.$$"; then
  rm -f "${TMPDIR:-/tmp}/format_check.$$"
  echo "format: ${#files[@]} files formatted"
  exit 0
fi
grep "warning:" "${TMPDIR:-/tmp}/format_check.$$" | cut -d: -f1 | sort | uniq -c
echo "format: fix with: clang-format -i \$(git ls-files '*.cpp' '*.h')"
rm -f "${TMPDIR:-/tmp}/format_check.$$"
exit 1
