#include "engine/direct/weight_uncertainty.h"
#include "engine/linalg/sparse_columns.h"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <limits>

namespace springfit {

std::optional<Vector> WeightStandardErrors(const SparseMatrix& a, const std::vector<bool>& usable,
                                           double residual_variance, int max_columns,
                                           Interruption* interruption) {
  const int n = static_cast<int>(a.cols());
  if (std::count(usable.begin(), usable.end(), true) > max_columns) return std::nullopt;
  Vector sigma = Vector::Constant(n, std::numeric_limits<double>::infinity());
  // Unit-norm columns for the factorisation, as in the NNLS solve; scaled back at the end.
  const std::optional<UnitColumnNormal> unit_normal = UnitNormalOf(a, usable);
  if (!unit_normal) return std::nullopt;
  const std::vector<int>& columns = unit_normal->columns;
  const Vector& scale = unit_normal->scale;
  if (columns.empty()) return sigma;
  Eigen::SimplicialLDLT<SparseMatrix> ldlt(unit_normal->normal);
  if (ldlt.info() != Eigen::Success) return std::nullopt;
  // Dependent columns show as (near-)zero pivots of the unit-diagonal normal matrix.
  const Vector& pivots = ldlt.vectorD();
  for (Eigen::Index i = 0; i < pivots.size(); ++i) {
    if (!(pivots[i] > kSingularUnitPivot)) return std::nullopt;
  }

  Vector unit = Vector::Zero(static_cast<Eigen::Index>(columns.size()));
  for (std::size_t c = 0; c < columns.size(); ++c) {
    ThrowIfInterrupted(interruption);
    const auto i = static_cast<Eigen::Index>(c);
    unit[i] = 1.0;
    const double inverse_diagonal = ldlt.solve(unit)[i];
    unit[i] = 0.0;
    sigma[columns[c]] = scale[i] * std::sqrt(std::max(inverse_diagonal, 0.0) * residual_variance);
  }
  return sigma;
}

}  // namespace springfit
