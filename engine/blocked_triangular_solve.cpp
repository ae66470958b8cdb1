#include "engine/blocked_triangular_solve.h"

namespace springfit {
namespace {

// The position of column j's diagonal in the factor's arrays (rows ascend within a column).
Eigen::Index DiagonalAt(const int* inner, Eigen::Index begin, Eigen::Index j) {
  Eigen::Index p = begin;
  while (inner[p] < j) ++p;
  return p;
}

}  // namespace

void SolveWithCholeskyFactor(const Eigen::SparseMatrix<double>& factor, RowBlock& b) {
  const Eigen::Index n = factor.cols();
  const Eigen::Index m = b.cols();
  const int* outer = factor.outerIndexPtr();
  const int* nonzeros = factor.innerNonZeroPtr();  // null when compressed
  const int* inner = factor.innerIndexPtr();
  const double* value = factor.valuePtr();
  const auto end = [&](Eigen::Index j) -> Eigen::Index {
    return nonzeros ? outer[j] + nonzeros[j] : outer[j + 1];
  };
  double* y = b.data();
  // L y = b, column by column: y_j = b_j / L_jj, then b_i -= L_ij y_j below it.
  for (Eigen::Index j = 0; j < n; ++j) {
    double* __restrict yj = y + j * m;
    bool zero = true;
    for (Eigen::Index c = 0; c < m && zero; ++c) zero = yj[c] == 0.0;
    if (zero) continue;  // (as Eigen's solve skips a zero entry)
    Eigen::Index p = DiagonalAt(inner, outer[j], j);
    const double diagonal = value[p];
    for (Eigen::Index c = 0; c < m; ++c) yj[c] /= diagonal;
    for (++p; p < end(j); ++p) {
      const double l = value[p];
      double* __restrict yi = y + static_cast<Eigen::Index>(inner[p]) * m;
      for (Eigen::Index c = 0; c < m; ++c) yi[c] -= yj[c] * l;
    }
  }
  // L^T x = y, from the last row up: x_j = (y_j - sum_i L_ij x_i) / L_jj.
  for (Eigen::Index j = n - 1; j >= 0; --j) {
    double* __restrict xj = y + j * m;
    Eigen::Index p = DiagonalAt(inner, outer[j], j);
    const double diagonal = value[p];
    for (++p; p < end(j); ++p) {
      const double l = value[p];
      const double* __restrict xi = y + static_cast<Eigen::Index>(inner[p]) * m;
      for (Eigen::Index c = 0; c < m; ++c) xj[c] -= l * xi[c];
    }
    for (Eigen::Index c = 0; c < m; ++c) xj[c] /= diagonal;
  }
}

}  // namespace springfit
