// Solves with a sparse Cholesky factor for many right-hand sides at once.
//
// Eigen's sparse triangular solve walks the whole factor once per right-hand side: on a 3D
// support (fem-block-3d, 3,000 free degrees of freedom) the factor does not stay in cache, and
// the probe fit's batched solves spent most of their time streaming it (bench/RESULTS.md, "Large
// 3D meshes"). Here the right-hand sides are stored row by row, so one pass over the factor
// updates all of them. Each right-hand side sees the same operations in the same order as in
// Eigen's solve, so on Eigen's factor the results are the same bits. CHOLMOD's supernodal
// factor is read the same way, column by column, in place of its solve's reference-BLAS
// kernels (twice as slow on 32 right-hand sides at 12,000 degrees of freedom).
#pragma once

#include <Eigen/Core>

namespace springfit {

// Right-hand sides stored row by row: row i holds every column's entry i.
using RowBlock = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Column j of a lower triangular factor from its diagonal down: `count` entries, the first the
// diagonal (rows[0] == j), the other rows ascending.
struct FactorColumn {
  const int* rows = nullptr;
  const double* values = nullptr;
  Eigen::Index count = 0;
};

// Overwrites b (n x m) with (L L^T)^-1 b, L given column by column by `column(j)`, in the
// factor's own (permuted) order: the caller permutes.
template <typename ColumnOf>
void SolveWithCholeskyFactor(Eigen::Index n, const ColumnOf& column, RowBlock& b) {
  const Eigen::Index m = b.cols();
  double* y = b.data();
  // L y = b, column by column: y_j = b_j / L_jj, then b_i -= L_ij y_j below it.
  for (Eigen::Index j = 0; j < n; ++j) {
    double* __restrict yj = y + j * m;
    bool zero = true;
    for (Eigen::Index c = 0; c < m && zero; ++c) zero = yj[c] == 0.0;
    if (zero) continue;  // (as Eigen's solve skips a zero entry)
    const FactorColumn l = column(j);
    for (Eigen::Index c = 0; c < m; ++c) yj[c] /= l.values[0];
    for (Eigen::Index p = 1; p < l.count; ++p) {
      const double lij = l.values[p];
      double* __restrict yi = y + static_cast<Eigen::Index>(l.rows[p]) * m;
      for (Eigen::Index c = 0; c < m; ++c) yi[c] -= yj[c] * lij;
    }
  }
  // L^T x = y, from the last row up: x_j = (y_j - sum_i L_ij x_i) / L_jj.
  for (Eigen::Index j = n - 1; j >= 0; --j) {
    double* __restrict xj = y + j * m;
    const FactorColumn l = column(j);
    for (Eigen::Index p = 1; p < l.count; ++p) {
      const double lij = l.values[p];
      const double* __restrict xi = y + static_cast<Eigen::Index>(l.rows[p]) * m;
      for (Eigen::Index c = 0; c < m; ++c) xj[c] -= lij * xi[c];
    }
    for (Eigen::Index c = 0; c < m; ++c) xj[c] /= l.values[0];
  }
}

}  // namespace springfit
