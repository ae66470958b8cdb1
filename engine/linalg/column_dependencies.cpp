#include "engine/linalg/column_dependencies.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/SPQRSupport>
#include <Eigen/SparseCore>

#include "engine/linalg/sparse_columns.h"
#include "engine/runtime/number_text.h"
#include "engine/runtime/options_check.h"

namespace springfit {
namespace {

using QrMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, SuiteSparse_long>;

// The smallest singular value of the upper triangular `r11` (an estimate from above) and its
// right singular vector: power iteration on (R11^T R11)^-1 from a fixed start, so the same
// matrix gives the same answer. 0 when a solve breaks down (a zero or non-finite pivot).
struct SmallestSingular {
  double value = 1.0;
  Vector vector;
};
SmallestSingular SmallestSingularOf(const QrMatrix& r11, int iterations) {
  const Eigen::Index n = r11.cols();
  SmallestSingular out;
  out.vector = Vector(n);
  for (Eigen::Index i = 0; i < n; ++i)
    out.vector[i] = 1.0 + 0.5 * std::sin(1.0 + static_cast<double>(i));
  if (n == 0) return out;
  out.vector.normalize();
  for (int it = 0; it < iterations; ++it) {
    Vector y = r11.transpose().triangularView<Eigen::Lower>().solve(out.vector);
    r11.triangularView<Eigen::Upper>().solveInPlace(y);
    const double growth = y.norm();  // |(R11^T R11)^-1 x| for the current unit x
    if (!std::isfinite(growth) || growth == 0.0) {
      out.value = 0.0;
      return out;
    }
    out.value = 1.0 / std::sqrt(growth);
    out.vector = y / growth;
  }
  return out;
}

// A basis of `a`'s columns with its triangular factor: A(:, columns) = Q R11, R11 confirmed
// well conditioned (its smallest singular value at least confirm_margin * rank_tolerance).
struct ConfirmedBasis {
  std::vector<int> columns;  // in R11's order
  QrMatrix r11;
  std::vector<int> dependent;  // the other columns, in order
  std::string failure;         // why no basis was confirmed; empty on success
};

// Heath's rank decides each column once, in the QR's order, so it keeps a dependent column
// whose residual stays above the tolerance. Such a column shows as a near-null vector of R11:
// the basis column it weighs most is moved to the dependent ones and the rest factored again,
// until R11 is confirmed or max_repairs are spent.
ConfirmedBasis ConfirmBasis(const SparseMatrix& a, const ColumnDependencyOptions& options,
                            Interruption* interruption) {
  ConfirmedBasis out;
  std::vector<int> live(static_cast<std::size_t>(a.cols()));
  for (std::size_t j = 0; j < live.size(); ++j) live[j] = static_cast<int>(j);
  for (int repair = 0;; ++repair) {
    QrMatrix columns = SelectColumns(a, live).cast<double>();
    columns.makeCompressed();
    Eigen::SPQR<QrMatrix> qr;
    qr.setPivotThreshold(options.rank_tolerance);
    qr.setSPQROrdering(options.ordering == ColumnDependencyOptions::Ordering::kMetis
                           ? SPQR_ORDERING_METIS
                           : SPQR_ORDERING_COLAMD);
    qr.compute(columns);
    ThrowIfInterrupted(interruption);
    if (qr.info() != Eigen::Success) {
      out.failure = "the sparse QR failed (out of memory, or a SuiteSparse error)";
      return out;
    }
    const Eigen::Index rank = qr.rank();
    // (A copy: colsPermutation() returns a temporary view, its indices die with it.)
    const Eigen::Matrix<SuiteSparse_long, Eigen::Dynamic, 1> perm = qr.colsPermutation().indices();
    out.columns.clear();
    for (Eigen::Index k = 0; k < static_cast<Eigen::Index>(live.size()); ++k) {
      const int column = live[static_cast<std::size_t>(perm[k])];
      (k < rank ? out.columns : out.dependent).push_back(column);
    }
    // R = [R11 R12] on its first `rank` rows, the basis columns first (A E = Q R).
    out.r11 = qr.matrixR().topLeftCorner(rank, rank);
    const SmallestSingular smallest = SmallestSingularOf(out.r11, options.confirm_iterations);
    if (smallest.value >= options.confirm_margin * options.rank_tolerance) break;
    if (repair == options.max_repairs) {
      out.failure = "the sparse QR's rank " + std::to_string(rank) + " is not confirmed after " +
                    std::to_string(repair) +
                    " repairs (smallest singular value of its basis about " +
                    NumberText(smallest.value) + ")";
      return out;
    }
    Eigen::Index weakest = 0;
    smallest.vector.cwiseAbs().maxCoeff(&weakest);
    out.dependent.push_back(out.columns[static_cast<std::size_t>(weakest)]);
    out.columns.erase(out.columns.begin() + weakest);
    live = out.columns;
  }
  std::sort(out.dependent.begin(), out.dependent.end());
  return out;
}

}  // namespace

void ColumnDependencyOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  check.Require(InOpenUnit(rank_tolerance), "rank_tolerance", rank_tolerance, "0 < value < 1");
  check.Require(InOpenUnit(circuit_tolerance), "circuit_tolerance", circuit_tolerance,
                "0 < value < 1");
  check.Require(confirm_margin >= 1.0, "confirm_margin", confirm_margin, "value >= 1");
  check.Require(confirm_iterations >= 1, "confirm_iterations", confirm_iterations, "value >= 1");
  check.Require(max_repairs >= 0, "max_repairs", max_repairs, "value >= 0");
  check.Require(max_trace_work >= 0.0, "max_trace_work", max_trace_work, "value >= 0");
}

ColumnDependencies FindColumnDependencies(const SparseMatrix& a,
                                          const ColumnDependencyOptions& options,
                                          Interruption* interruption) {
  options.Validate();
  ColumnDependencies out;
  if (a.cols() == 0) {
    out.analysed = true;
    return out;
  }
  if (a.nonZeros() == 0) {
    out.not_analysed = "no column has an entry";
    return out;
  }
  const ConfirmedBasis basis = ConfirmBasis(a, options, interruption);
  out.rank = static_cast<int>(basis.columns.size());
  if (!basis.failure.empty()) {
    out.not_analysed = basis.failure;
    return out;
  }
  const SparseMatrix a_basis = SelectColumns(a, basis.columns);
  const double work = 2.0 * static_cast<double>(basis.r11.nonZeros() + a_basis.nonZeros()) *
                      static_cast<double>(basis.dependent.size());
  if (work > options.max_trace_work) {
    out.not_analysed = std::to_string(basis.dependent.size()) + " dependencies among " +
                       std::to_string(a.cols()) + " columns are too many to trace";
    return out;
  }
  out.analysed = true;
  const auto upper = basis.r11.triangularView<Eigen::Upper>();
  const auto lower = basis.r11.transpose().triangularView<Eigen::Lower>();
  // Least squares by the corrected semi-normal equations (R11^T R11 c = A_B^T a_j, then once
  // more on the residual): Q is not kept, and one correction gives the QR's accuracy.
  auto solve = [&](const Vector& rhs) {
    Vector c = lower.solve(Vector(a_basis.transpose() * rhs));
    upper.solveInPlace(c);
    return c;
  };
  for (const int column : basis.dependent) {
    ThrowIfInterrupted(interruption);
    const Vector target = Vector(a.col(column));
    Vector c = solve(target);
    c += solve(target - a_basis * c);
    ColumnDependencies::Circuit circuit;
    circuit.column = column;
    const double largest = c.size() > 0 ? std::max(c.cwiseAbs().maxCoeff(), 1.0) : 1.0;
    for (Eigen::Index b = 0; b < c.size(); ++b) {
      if (std::abs(c[b]) > options.circuit_tolerance * largest)
        circuit.basis.emplace_back(basis.columns[static_cast<std::size_t>(b)], c[b]);
    }
    std::sort(circuit.basis.begin(), circuit.basis.end());
    out.circuits.push_back(std::move(circuit));
  }
  return out;
}

}  // namespace springfit
