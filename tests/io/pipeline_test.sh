#!/usr/bin/env bash
# The README's pipeline (gmsh -> springfit import -> run -> export), run exactly as the README
# writes it: the commands between its <!-- pipeline --> markers, in a scratch directory, with
# this build's springfit first on the PATH. Then what they wrote is checked.
# Usage: pipeline_test.sh SPRINGFIT SOURCE_DIR
set -u
sf=$1
src=$2
source "$(dirname "$0")/../checks.sh"

sed -n '/^<!-- pipeline -->$/,/^<!-- \/pipeline -->$/p' "$src/README.md" | sed '1,2d;$d' | sed '$d' >"$tmp/pipeline.sh"
[ "$(grep -c . "$tmp/pipeline.sh")" -eq 5 ] || fail "the README's pipeline block: $(cat "$tmp/pipeline.sh")"
mkdir "$tmp/bin" && ln -s "$(cd "$(dirname "$sf")" && pwd)/$(basename "$sf")" "$tmp/bin/springfit"
ln -s "$src/examples" "$tmp/examples"
(cd "$tmp" && PATH="$tmp/bin:$PATH" bash -e pipeline.sh >"$tmp/out" 2>&1) || fail "the pipeline failed: $(tail -5 "$tmp/out")"

python3 - "$tmp" <<'PY' || fail "the pipeline's files"
import json, sys, xml.etree.ElementTree as ET
tmp = sys.argv[1]
scene = json.load(open(tmp + "/inclusion.json"))
assert scene["reference"]["type"] == "fem" and len(scene["reference"]["element_materials"]) == len(scene["reference"]["elements"])
assert {"left", "right", "top", "bottom", "tissue", "inclusion"} <= set(scene["node_sets"])
r = json.load(open(tmp + "/result.json"))
assert r["rms_error"] < r["baseline"]["rms_error"], (r["rms_error"], r["baseline"]["rms_error"])
assert r["outcome"]["verdict"] in ("usable", "doubtful"), r["outcome"]  # doubtful: exit 12, goes on
vtu = ET.parse(tmp + "/model.vtu").getroot().find("UnstructuredGrid/Piece")
assert int(vtu.get("NumberOfCells")) == len(r["springs"]) + len(scene["reference"]["elements"]) and int(vtu.get("NumberOfPoints")) == len(scene["nodes"])
ff = ET.parse(tmp + "/model.scn").getroot().find(".//SpringForceField")
assert len(ff.get("spring").split()) == 5 * len(r["springs"])
PY

finish pipeline
