#include "engine/model/rigidity.h"

#include <cmath>
#include <vector>

#include <Eigen/SPQRSupport>
#include <Eigen/SparseCore>

#include "engine/linalg/singular_values.h"

namespace springfit {

namespace {

// Up to this many unknowns a dense SVD (a fraction of a second) confirms a sparse QR's rank.
constexpr int kDenseCheckMaxColumns = 600;

}  // namespace

int RigidityRankDeficiency(const SpringGeometry& geometry, const FreeNodes& free,
                           const ActiveSprings& springs, double tolerance, int suspected) {
  const int d = geometry.dimension;
  const int n = d * free.count;
  if (n == 0) return 0;
  using Index = SuiteSparse_long;
  std::vector<Eigen::Triplet<double, Index>> entries;
  entries.reserve(static_cast<std::size_t>(springs.size()) * 2 * d);
  Index rows = 0;
  for (int a = 0; a < springs.size(); ++a) {
    const int s = springs.index[a];
    const int fi = free.free_index[geometry.pairs[s].first];
    const int fj = free.free_index[geometry.pairs[s].second];
    if (fi < 0 && fj < 0) continue;  // between constrained nodes: no row on the unknowns
    const double l = geometry.rest_length[s];
    for (int c = 0; c < d; ++c) {
      const double direction = geometry.rest_separation[d * s + c] / l;
      if (direction == 0.0) continue;
      if (fi >= 0) entries.emplace_back(rows, d * fi + c, direction);
      if (fj >= 0) entries.emplace_back(rows, d * fj + c, -direction);
    }
    ++rows;
  }
  // No spring acts on a free node: every coordinate is free to move (and SuiteSparseQR
  // refuses a matrix without entries).
  if (entries.empty()) return n;
  Eigen::SparseMatrix<double, Eigen::ColMajor, Index> r(rows, n);
  r.setFromTriplets(entries.begin(), entries.end());
  // Unit columns: the QR's tolerance is then relative to each coordinate's own stiffness.
  for (Index c = 0; c < n; ++c) {
    const double norm = r.col(c).norm();
    if (norm > 0.0) r.col(c) /= norm;
  }
  r.makeCompressed();
  Eigen::SPQR<Eigen::SparseMatrix<double, Eigen::ColMajor, Index>> qr;
  qr.setPivotThreshold(tolerance);
  qr.compute(r);
  if (qr.info() != Eigen::Success) return n;  // out of memory: nothing is known to be rigid
  const int deficiency = n - static_cast<int>(qr.rank());
  // Heath's rank can come out too high on an ill-conditioned R (a thin strip: a dependent
  // column keeps a residual norm above the tolerance), so fewer modes than the LDLT's
  // near-zero eigenvalues are checked by a dense SVD where that is cheap.
  if (deficiency >= suspected || n > kDenseCheckMaxColumns) return deficiency;
  const Matrix dense = Matrix(r);
  const Vector sigma = SingularValues(dense);
  int small = n - static_cast<int>(sigma.size());  // columns beyond the rows
  for (Eigen::Index i = 0; i < sigma.size(); ++i) small += sigma[i] <= tolerance ? 1 : 0;
  return small;
}

}  // namespace springfit
