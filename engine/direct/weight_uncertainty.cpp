#include "engine/direct/weight_uncertainty.h"

#include <Eigen/SparseCholesky>
#include <cmath>
#include <limits>

namespace springfit {

std::optional<Vector> WeightStandardErrors(const SparseMatrix& a, const std::vector<bool>& usable,
                                           double residual_variance, int max_columns) {
  const int n = static_cast<int>(a.cols());
  std::vector<int> columns;
  for (int j = 0; j < n; ++j) {
    if (usable[j]) columns.push_back(j);
  }
  if (static_cast<int>(columns.size()) > max_columns) return std::nullopt;
  Vector sigma = Vector::Constant(n, std::numeric_limits<double>::infinity());
  if (columns.empty()) return sigma;

  // Unit-norm columns for the factorisation, as in the NNLS solve; scaled back at the end.
  Vector scale(static_cast<Eigen::Index>(columns.size()));
  for (std::size_t c = 0; c < columns.size(); ++c) {
    const double norm = a.col(columns[c]).norm();
    if (!(norm > 0.0)) return std::nullopt;
    scale[static_cast<Eigen::Index>(c)] = 1.0 / norm;
  }
  const SparseMatrix sub = SelectColumns(a, columns) * scale.asDiagonal();
  const SparseMatrix normal = sub.transpose() * sub;
  Eigen::SimplicialLDLT<SparseMatrix> ldlt(normal);
  if (ldlt.info() != Eigen::Success) return std::nullopt;
  // Dependent columns show as (near-)zero pivots of the unit-diagonal normal matrix.
  const Vector& pivots = ldlt.vectorD();
  for (Eigen::Index i = 0; i < pivots.size(); ++i) {
    if (!(pivots[i] > 1e-13)) return std::nullopt;
  }

  Vector unit = Vector::Zero(static_cast<Eigen::Index>(columns.size()));
  for (std::size_t c = 0; c < columns.size(); ++c) {
    const auto i = static_cast<Eigen::Index>(c);
    unit[i] = 1.0;
    const double inverse_diagonal = ldlt.solve(unit)[i];
    unit[i] = 0.0;
    sigma[columns[c]] = scale[i] * std::sqrt(std::max(inverse_diagonal, 0.0) * residual_variance);
  }
  return sigma;
}

}  // namespace springfit
