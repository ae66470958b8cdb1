#!/usr/bin/env bash
# The database on a real 8 MiB tmpfs, filled while jobs run and a client watches: run
# disk_full_test.py in a private mount namespace (nothing is mounted outside this test), as root
# (unshare --mount) or as a user with user namespaces (unshare --map-root-user --mount).
# Usage: disk_full_test.sh SPRINGFITD SPRINGFIT SOURCE_DIR
set -u
here=$(cd "$(dirname "$0")" && pwd)
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
inner='mount -t tmpfs -o size=8m springfit-test "$0" && exec python3 "$1/disk_full_test.py" "$2" "$3" "$4" "$0"'
if unshare --mount --propagation private true 2>/dev/null; then
  unshare --mount --propagation private bash -c "$inner" "$dir" "$here" "$@"
elif unshare --map-root-user --mount true 2>/dev/null; then
  unshare --map-root-user --mount bash -c "$inner" "$dir" "$here" "$@"
else
  echo "FAIL: cannot mount a tmpfs in a private mount namespace here (unshare --mount, as root or with user namespaces)"
  exit 1
fi
