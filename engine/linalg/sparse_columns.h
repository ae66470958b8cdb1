// Columns of a sparse matrix: a selection of them, and their normal matrix at unit norm (the
// force balance's, engine/problem/force_balance.h, and any other least-squares design matrix).
#pragma once

#include <optional>
#include <vector>

#include "engine/linalg/linalg.h"

namespace springfit {

// The columns of `a` listed in `columns`, in that order, as a new matrix.
SparseMatrix SelectColumns(const SparseMatrix& a, const std::vector<int>& columns);

// The normal matrix of the usable columns scaled to unit norm: its diagonal is 1, so that the
// factorisations of the standard errors and of the scale pinning judge pivots unit-free.
struct UnitColumnNormal {
  std::vector<int> columns;  // the usable columns, in order
  Vector scale;              // 1 / |a_j| per listed column
  SparseMatrix normal;       // (A S)^T (A S) over them
};
// nullopt when a usable column is zero.
std::optional<UnitColumnNormal> UnitNormalOf(const SparseMatrix& a,
                                             const std::vector<bool>& usable);
// A pivot of a unit-diagonal normal matrix at or below this marks dependent columns.
inline constexpr double kSingularUnitPivot = 1e-13;

}  // namespace springfit
