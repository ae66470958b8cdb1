// How well the force balance determines each spring weight: the standard error of the
// least-squares estimate, sigma_j^2 = s^2 [(A^T A)^-1]_jj over the usable columns, with s^2
// the residual variance. The data's noise (measured positions, or round-off for an MSS
// reference) sets s; the geometry of the load cases sets (A^T A)^-1.
#pragma once
#include <optional>
#include <vector>

#include "engine/problem/force_balance.h"
#include "engine/runtime/interruption.h"

namespace springfit {

// One linear solve per usable column with the factorised normal matrix, so only up to
// `max_columns` usable columns (nullopt beyond, or when the columns are linearly dependent:
// then some weights are not determined at all). Unusable columns get +infinity. Throws
// Interrupted when `interruption` stops it.
std::optional<Vector> WeightStandardErrors(const SparseMatrix& a, const std::vector<bool>& usable,
                                           double residual_variance, int max_columns,
                                           Interruption* interruption = nullptr);

}  // namespace springfit
