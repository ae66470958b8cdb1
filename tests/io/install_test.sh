#!/usr/bin/env bash
# `cmake --install`: the programs, systemd units, documents and examples land where the README
# says, the units start the installed daemon, and the README's pipeline runs with the installed
# springfit alone (the build directory out of the PATH). Also with DESTDIR, as a package does.
# Usage: install_test.sh BUILD_DIR SOURCE_DIR
set -u
build=$1
src=$(cd "$2" && pwd)
source "$(dirname "$0")/../checks.sh"

prefix="$tmp/prefix"
cmake --install "$build" --prefix "$prefix" >"$tmp/install.log" 2>&1 || fail "cmake --install: $(tail -5 "$tmp/install.log")"
for f in bin/springfit bin/springfitd lib/systemd/system/springfitd.service \
  lib/systemd/system/springfitd-worker.service share/doc/springfit/README.md \
  share/doc/springfit/RPC.md share/doc/springfit/MODEL.md share/doc/springfit/examples/springfitd.env \
  share/springfit/examples/paper-iso-5x5.json share/springfit/examples/pipeline/inclusion.geo; do
  [ -e "$prefix/$f" ] || fail "not installed: $f"
done
[ -x "$prefix/bin/springfitd" ] || fail "springfitd is not executable"
# The units run the installed daemon and point at the installed documents, not /usr/local.
for unit in springfitd springfitd-worker; do
  exec_path=$(sed -n 's/^ExecStart=\([^ ]*\).*/\1/p' "$prefix/lib/systemd/system/$unit.service")
  [ "$exec_path" = "$prefix/bin/springfitd" ] || fail "$unit.service starts '$exec_path'"
  grep -q "^Documentation=file://$prefix/share/doc/springfit/RPC.md$" "$prefix/lib/systemd/system/$unit.service" \
    || fail "$unit.service documentation: $(grep Documentation "$prefix/lib/systemd/system/$unit.service")"
done
"$prefix/bin/springfitd" --help >/dev/null 2>&1 || fail "the installed springfitd does not start"
# The README's pipeline with the installed program only.
bash "$(dirname "$0")/pipeline_test.sh" "$prefix/bin/springfit" "$src" >"$tmp/pipeline.log" 2>&1 \
  || fail "the README's pipeline with the installed springfit: $(tail -5 "$tmp/pipeline.log")"
# A package build installs into a staging root: every file under DESTDIR, the units naming the
# final prefix.
DESTDIR="$tmp/stage" cmake --install "$build" --prefix /usr >"$tmp/stage.log" 2>&1 || fail "DESTDIR install: $(tail -3 "$tmp/stage.log")"
[ -x "$tmp/stage/usr/bin/springfit" ] || fail "DESTDIR: no usr/bin/springfit"
grep -q "^ExecStart=/usr/bin/springfitd " "$tmp/stage/usr/lib/systemd/system/springfitd.service" \
  || fail "DESTDIR: the unit starts $(grep ExecStart "$tmp/stage/usr/lib/systemd/system/springfitd.service")"

finish install
