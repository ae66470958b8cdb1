// The built-in example scenes (`springfit example NAME`), also committed under examples/.
//
// Each generator builds its scene deterministically and checks that the reference stays
// unambiguous under every load case: no cell of the mesh inverts (docs/ARCHITECTURE.md, "Paper7
// load cases").
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "engine/api/examples.h"
#include "engine/api/scene.h"
#include "engine/examples/simplex_mesh.h"

namespace springfit::examples {

// The example scenes' builders are on the surface (engine/api/examples.h); the catalogue that
// names them, and loads the kidney's mesh from its Gmsh file, is io/example_catalog.h
// (`springfit example`). Here: their building blocks, also used by the benchmarks and tests.

// A regular grid of n[0] x n[1] (x n[2]) nodes with the given spacing, numbered with x fastest.
Vector GridNodes(const std::vector<int>& n, double spacing);

// All pairs of the 8 (2D) or 26 (3D) grid neighbourhood of GridNodes(n, spacing).
std::vector<NodePair> GridNeighbourSprings(const std::vector<int>& n);

// The paper's seven load cases (docs/ARCHITECTURE.md, "Paper7 load cases") on any node set,
// choosing fixed and loaded nodes from the bounding box: nodes within `band` (a fraction of the
// extent along that axis; 0 = exactly on the boundary) of the minimum are fixed, those within it of
// the maximum loaded with `magnitude` per node. 2D: bottom fixed, top loaded +y, -y, +x, -x; left
// fixed, right loaded +x, +y, -y. 3D adds z: bottom (z) fixed, top loaded +z, -z, +x, -x, +y;
// left (x) fixed, right loaded +x, +y, -y, +z (9 cases).
std::vector<LoadCase> Paper7LoadCases(int dimension, const Vector& rest, double magnitude,
                                      double band = 0.0);

// The paper7 patterns: a case's name, the axis whose low side is fixed (its high side is
// loaded), the axis of the load and its sign.
struct Paper7Pattern {
  const char* name;
  int fixed_axis;
  int load_axis;
  double sign;
};
const std::vector<Paper7Pattern>& Paper7Patterns(int dimension);

// The nodes within `band` (a fraction of the extent along `axis`; 0 = exactly on the
// boundary, within 1e-9 of the diagonal) of the low or the high side along `axis`.
std::vector<int> SideNodes(int dimension, const Vector& rest, int axis, bool low, double band);

// Rescales every load case's forces and tractions so that the reference's largest nodal
// displacement in the small-load (linear) limit is `strain` times the scene's extent
// (docs/ARCHITECTURE.md, "Paper7 load cases": examples keep loads at moderate strain).
void ScaleLoadsToStrain(Scene& scene, double strain);

// Throws std::logic_error when a simplex of `simplices` (triangles in 2D, tetrahedra in 3D,
// node indices) is inverted or flattened in some reference equilibrium of `scene`.
void CheckFoldFree(const Scene& scene, const std::vector<std::vector<int>>& simplices);

// A grid whose reference keeps only part of the grid neighbourhood, with varied stiffness:
// every axis-parallel spring; on every square face one diagonal, and the other with
// probability 1/2; in 3D every body diagonal with probability 1/2 (triangulated faces keep
// each cell rigid). Stiffness log-uniform over `stiffness_decades` decades around 1. Loads:
// paper7 at 5% strain. Deterministic in `seed`; for tests and benchmarks at any size.
Scene ThinnedGrid(const std::vector<int>& n, std::uint64_t seed, double stiffness_decades);

// The simplices of a grid (each cell split both ways in 2D; the eight corner tetrahedra of
// each cube in 3D), for CheckFoldFree.
std::vector<std::vector<int>> GridSimplices(const std::vector<int>& n);

}  // namespace springfit::examples
