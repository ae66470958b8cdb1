#!/usr/bin/env bash
# End-to-end checks of the springfit program: render and plot, the SVG figures of result files,
# and their exit codes.
# Usage: cli_render_test.sh SPRINGFIT SOURCE_DIR
set -u
sf=$1
src=$2
source "$(dirname "$0")/cli_support.sh"  # (and ../checks.sh)

# The exact recovery to draw (cli_run_test.sh checks it).
paper_result "$tmp/result.json"

# render and plot: SVG files from result files; the wrong springs are drawn one line each.
expect_exit 0 "render exact" "$sf" render "$tmp/result.json" -o "$tmp/exact.svg"
"$sf" run "$src/examples/paper-iso-5x5.json" --strategy paper --generations 5 -q -o "$tmp/short.json" >/dev/null
expect_exit 0 "render short" "$sf" render "$tmp/short.json" --case 1 -o "$tmp/short.svg"
expect_exit 0 "plot" "$sf" plot "$tmp/result.json" "$tmp/short.json" -o "$tmp/plot.svg" --title "iso"
# plot --x generations: the paper's Figure 2 axis (5 generations: decades 1 and 10); render
# and plot write SVG only, and say so for another name (nothing written).
expect_exit 0 "plot generations" "$sf" plot "$tmp/short.json" --x generations -o "$tmp/gen.svg"
grep -q 'Normalized error against generations' "$tmp/gen.svg" || fail "plot --x generations: no title"
grep -q 'y="442.00" text-anchor="middle">10</text>' "$tmp/gen.svg" || fail "plot --x generations: no decade 10 on the x axis"
grep -q 'y="442.00" text-anchor="middle">1e-' "$tmp/gen.svg" && fail "plot --x generations drew seconds"
expect_exit 64 "plot png" "$sf" plot "$tmp/short.json" -o "$tmp/plot.png"
grep -q "does not end in .svg" "$tmp/err" || fail "plot png: $(cat "$tmp/err")"
[ -e "$tmp/plot.png" ] && fail "plot wrote a .png file"
expect_exit 64 "render pdf" "$sf" render "$tmp/short.json" -o "$tmp/t.pdf"
[ -e "$tmp/t.pdf" ] && fail "render wrote a .pdf file"
python3 - "$tmp/exact.svg" "$tmp/short.svg" "$tmp/short.json" "$tmp/plot.svg" <<'PY' || fail "render/plot content"
import json, sys, xml.etree.ElementTree as ET
ns = "{http://www.w3.org/2000/svg}"
def lines(path, cls):  # shapes of a class, the legend sample excluded
    return sum(1 for e in ET.parse(path).iter() if e.get("class") == cls) - 1
assert lines(sys.argv[1], "missing") == 0 and lines(sys.argv[1], "extra") == 0
short = json.load(open(sys.argv[3]))
assert short["hamming"] > 0, short["hamming"]
assert lines(sys.argv[2], "missing") == len(short["missing"]), "one load case: one line per missing spring"
assert lines(sys.argv[2], "extra") == len(short["extra"])
plot = ET.parse(sys.argv[4])
assert sum(1 for e in plot.iter(ns + "polyline")) == 2
assert sum(1 for e in plot.iter(ns + "circle") if e.get("class") == "exact0") == 1  # the exact run's marker
PY
# --rest: the two topologies at rest, one pair of panels, no load case drawn; --node-numbers
# writes every node's index in each panel.
expect_exit 0 "render --rest" "$sf" render "$tmp/short.json" --rest --node-numbers -o "$tmp/rest.svg"
python3 - "$tmp/rest.svg" "$tmp/short.json" <<'PY' || fail "render --rest content"
import json, sys, xml.etree.ElementTree as ET
ns = "{http://www.w3.org/2000/svg}"
root = ET.parse(sys.argv[1]).getroot()
short = json.load(open(sys.argv[2]))
n = len(short["scene_definition"]["nodes"])
of = lambda cls: [e for e in root.iter() if e.get("class") == cls]
assert len([e for e in of("panel") if e.tag == ns + "rect"]) == 2
numbers = [t.text for t in of("number")]
assert sorted(numbers) == sorted([str(i) for i in range(n)] * 2), numbers[:10]
assert len(of("missing")) - 1 == len(short["missing"]) and len(of("extra")) - 1 == len(short["extra"])
assert not of("rest") and not of("force") and not of("fixed"), "a load case drawn at rest"
texts = "".join(t.text or "" for t in root.iter(ns + "text"))
assert "identified topology, at rest" in texts and "displacements" not in texts, texts[:300]
PY
expect_exit 64 "render --rest --case" "$sf" render "$tmp/short.json" --rest --case 0 -o "$tmp/x.svg"
expect_exit 2 "render missing file" "$sf" render "$tmp/nope.json" -o "$tmp/x.svg"
expect_exit 2 "render load case out of range" "$sf" render "$tmp/short.json" --case 7 -o "$tmp/x.svg"
grep -q "load case 7 out of range" "$tmp/err" || fail "render names the load case: $(cat "$tmp/err")"
"$sf" run "$src/examples/paper-iso-5x5.json" -q --json >"$tmp/stdout-result.json"
expect_exit 2 "render without a scene" "$sf" render "$tmp/stdout-result.json" -o "$tmp/x.svg"
grep -q -- "--scene" "$tmp/err" || fail "render asks for --scene: $(cat "$tmp/err")"
expect_exit 0 "render with --scene" "$sf" render "$tmp/stdout-result.json" --scene "$src/examples/paper-iso-5x5.json" -o "$tmp/x.svg"
expect_exit 2 "plot without a trace" "$sf" plot "$tmp/stdout-result.json" -o "$tmp/x.svg"
expect_exit 64 "render without -o" "$sf" render "$tmp/short.json"

finish cli_render
