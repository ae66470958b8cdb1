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
  share/doc/springfit/proto/RPC.md share/doc/springfit/proto/MODEL.md share/doc/springfit/examples/springfitd.env \
  share/springfit/examples/paper-iso-5x5.json share/springfit/examples/pipeline/inclusion.geo; do
  [ -e "$prefix/$f" ] || fail "not installed: $f"
done
[ -x "$prefix/bin/springfitd" ] || fail "springfitd is not executable"
# The units run the installed daemon and point at the installed documents, not /usr/local.
for unit in springfitd springfitd-worker; do
  exec_path=$(sed -n 's/^ExecStart=\([^ ]*\).*/\1/p' "$prefix/lib/systemd/system/$unit.service")
  [ "$exec_path" = "$prefix/bin/springfitd" ] || fail "$unit.service starts '$exec_path'"
  grep -q "^Documentation=file://$prefix/share/doc/springfit/proto/RPC.md$" "$prefix/lib/systemd/system/$unit.service" \
    || fail "$unit.service documentation: $(grep Documentation "$prefix/lib/systemd/system/$unit.service")"
done
"$prefix/bin/springfitd" --help >/dev/null 2>&1 || fail "the installed springfitd does not start"
# Every relative link in the installed documents finds its installed file (the README's
# proto/RPC.md, docs/ARCHITECTURE.md, deploy/, ...), as a reader of /usr/local/share/doc follows them.
python3 - "$prefix/share/doc/springfit" >"$tmp/links.log" 2>&1 <<'PY' || fail "installed documents with broken links: $(cat "$tmp/links.log")"
import os, re, sys
root = sys.argv[1]
broken, seen = [], 0
for folder, _, files in os.walk(root):
    for name in files:
        if not name.endswith(".md"):
            continue
        path = os.path.join(folder, name)
        for m in re.finditer(r"\]\(([^)#:\s]+)(#[^)]*)?\)", open(path).read()):
            seen += 1
            if not os.path.exists(os.path.normpath(os.path.join(folder, m.group(1)))):
                broken.append(f"{os.path.relpath(path, root)} -> {m.group(1)}")
assert seen >= 20, f"only {seen} links found: the check reads nothing"
assert not broken, "; ".join(broken)
PY
# The Python client, installed with the programs where the system's Python looks under the
# prefix (lib/python3.X/dist-packages), and importable from there.
client_dir=$(ls -d "$prefix"/lib/python3*/dist-packages 2>/dev/null | head -1)
[ -n "$client_dir" ] && [ -f "$client_dir/springfit_client/__init__.py" ] \
  || fail "the Python client is not installed under $prefix/lib/python3*/dist-packages"
PYTHONPATH="$client_dir" python3 -c "import springfit_client as s; s.Client; print(s.__file__)" >"$tmp/py.log" 2>&1 \
  || fail "the installed Python client does not import: $(cat "$tmp/py.log")"
grep -qx "$client_dir/springfit_client/__init__.py" "$tmp/py.log" || fail "imported another springfit_client: $(cat "$tmp/py.log")"
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
