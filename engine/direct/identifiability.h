// Which spring weights the scene's load cases can tell apart, before any search.
//
// From the force balance at the reference's equilibria (engine/problem/force_balance.h):
//  - unseen springs: no load case changes their length, so their column of A is zero and no
//    data says anything about them;
//  - dependent groups: springs whose columns are linearly dependent, so that different
//    weights (topologies) balance the same forces in every load case. The groups are the
//    connected components of the fundamental circuits of A's columns (relative to the basis
//    a sparse rank-revealing QR chooses, engine/linalg/column_dependencies.h): two springs share a
//    group when some dependency involves both, and the partition does not depend on the
//    basis chosen (two fill orderings, two bases, give the same groups on
//    fem-kidney-2d-fine).
//  - for each group, a suggested extra load case that separates it: among single nodal
//    forces on the group's free nodes along each axis, applied with the constraints of an
//    existing load case, the one whose small-load response gives the group's columns the
//    most independent new rows. Tried on the reference itself in the small-load limit (its
//    stiffness at rest, an MSS's or an FEM model's: engine/problem/rest_stiffness.h, factorised
//    once per support); for a positions reference no model exists to try loads on, so there is
//    no suggestion.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "engine/api/identifiability_report.h"
#include "engine/api/problem.h"
#include "engine/linalg/column_dependencies.h"
#include "engine/problem/force_balance.h"

namespace springfit {

struct IdentifiabilityOptions {
  // The QR's tolerances and bounds, on A's columns scaled to unit norm.
  ColumnDependencyOptions dependencies;
  double unseen_strain = kUnseenStrain;
  // A sparse QR of A over the seen genes (engine/linalg/column_dependencies.h; A has a column per
  // gene and a row per free coordinate and load case) that cannot be interrupted. Its time and
  // memory grow faster than the genes (the QR's fill): bench/RESULTS.md, "Identifiability at
  // scale", has them from the examples to the 10,582-node block's 67,809 genes, which this bound
  // leaves out. Beyond the bound no group is analysed, and the report says so.
  int max_genes = 30000;
  // A group gets a suggestion when its springs times its dependencies stay below this: each
  // trial load multiplies a block of that size (a one-load-case 30x30 grid would take minutes).
  int max_suggestion_size = 5000;

  // Throws std::invalid_argument naming the field, its value and the rule it breaks.
  void Validate() const;
};

// Throws Interrupted when `interruption` stops it (between the QR's steps, and between the
// suggestions' trial solves).
IdentifiabilityReport AnalyseIdentifiability(const Problem& problem,
                                             const IdentifiabilityOptions& options = {},
                                             Interruption* interruption = nullptr);
}  // namespace springfit
