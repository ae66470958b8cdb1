#include "engine/direct/scale_pinning.h"
#include "engine/linalg/sparse_columns.h"

#include <Eigen/SparseCholesky>

namespace springfit {
namespace {

// The gene whose component of A's (approximate) null vector is largest; -1 when there is
// none to find.
int LargestNullComponent(const SparseMatrix& a, const std::vector<bool>& usable,
                         const PinOptions& options) {
  std::optional<UnitColumnNormal> unit_normal = UnitNormalOf(a, usable);
  if (!unit_normal || unit_normal->columns.empty()) return -1;
  SparseMatrix& normal = unit_normal->normal;
  SparseMatrix identity(normal.rows(), normal.cols());
  identity.setIdentity();
  normal += options.shift * identity;
  const Eigen::SimplicialLDLT<SparseMatrix> ldlt(normal);
  if (ldlt.info() != Eigen::Success) return -1;
  Vector x = Vector::Ones(normal.rows()).normalized();
  for (int it = 0; it < options.inverse_iterations; ++it) x = ldlt.solve(x).normalized();
  // The sign of a null vector is free; that of the weights is not. Its largest component on
  // the unit columns (the spring whose force the balance leans on most), not in weight
  // units, where a barely strained column's huge 1/|a_j| would magnify round-off and noise.
  if (x.sum() < 0.0) x = -x;
  Eigen::Index best = 0;
  x.maxCoeff(&best);
  return unit_normal->columns[static_cast<std::size_t>(best)];
}

}  // namespace

std::optional<PinnedSolution> SolvePinnedNnls(const SparseMatrix& a,
                                              const std::vector<bool>& usable,
                                              const PinOptions& pins, const NnlsOptions& nnls,
                                              Interruption* interruption) {
  const int pin = LargestNullComponent(a, usable, pins);
  if (pin < 0) return std::nullopt;
  PinnedSolution s;
  s.pinned_gene = pin;
  s.rhs = -Vector(a.col(pin));
  s.columns = usable;
  s.columns[pin] = false;
  s.nnls = SolveNnls(a, s.rhs, s.columns, nnls, interruption);
  return s;
}

}  // namespace springfit
