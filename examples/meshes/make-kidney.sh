#!/usr/bin/env bash
# Regenerates the kidney example meshes from their outline:
#   kidney-2d.geo -> kidney-2d.msh       (gmsh, MSH 2.2 ASCII, lc 0.9: 99 nodes, 165 triangles)
#   kidney-2d.geo -> kidney-2d-fine.msh  (lc 0.325: 626 nodes, 1164 triangles)
# The built-in examples (kidney-2d, fem-kidney-2d, -nl, -fine) read these files through
# springfit's mesh importer (io/example_catalog.cpp); the build embeds them, so `springfit
# example` needs no file at run time. Single-threaded meshing: running it twice gives
# identical files (generated with gmsh 4.8.4; another version may mesh differently, and the
# examples/*.json of the kidney examples would then need `springfit example NAME -o`).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
gmsh_bin="${GMSH:-gmsh}"
ver="$("$gmsh_bin" --version 2>&1 | tail -n 1)"
if [[ "$ver" != "4.8.4" ]]; then
  echo "warning: gmsh $ver found; the kidney meshes were generated with gmsh 4.8.4 and may differ" >&2
fi
"$gmsh_bin" -2 -format msh2 -nt 1 "$here/kidney-2d.geo" -o "$here/kidney-2d.msh" >/dev/null
"$gmsh_bin" -2 -format msh2 -nt 1 -setnumber lc 0.325 "$here/kidney-2d.geo" \
  -o "$here/kidney-2d-fine.msh" >/dev/null
echo "kidney-2d.msh, kidney-2d-fine.msh regenerated"
