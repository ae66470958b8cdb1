#include "engine/linalg/nnls.h"

#include <Eigen/CholmodSupport>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>

#include "engine/linalg/sparse_columns.h"
#include "engine/runtime/options_check.h"

namespace springfit {
namespace {

// Below this many columns the simplicial factorisation is faster, above it the supernodal one
// (measured with bench/direct_bench from grid3d-4x4x4 to a 12x12x12 grid: bench/RESULTS.md,
// "Strategy direct").
constexpr std::size_t kSupernodalFromColumns = 2000;
constexpr double kRidge = 1e-10;
constexpr int kDefaultRounds = 100;  // NnlsOptions::max_iterations = 0
// The gradient on the free set that still counts as a solved least-squares problem, relative
// to |A^T b|: refinement reaches about 1e-12 on healthy problems.
constexpr double kSolveAccuracy =
    1e-6;  // relative to the unit diagonal of the scaled normal matrix

// z refined against the residual of the scaled problem on the selected columns `sub`.
template <class Factor, class Sub>
Vector Refined(const Factor& factor, const Sub& sub, const Vector& b, int refinement_steps) {
  Vector z = factor.solve(sub.transpose() * b);
  for (int step = 0; step < refinement_steps; ++step) {
    const Vector r = b - sub * z;
    z += factor.solve(sub.transpose() * r);
  }
  return z;
}

// The least-squares solution on the columns `free` (unconstrained), refined.
Vector SolveOn(const SparseMatrix& a, const Vector& b, const std::vector<int>& free,
               int refinement_steps, int& factorizations) {
  if (free.empty()) return Vector();
  const SparseMatrix sub = SelectColumns(a, free);
  const SparseMatrix normal = sub.transpose() * sub;
  // CHOLMOD's supernodal Cholesky (dense BLAS blocks) is many times faster than a simplicial
  // one on the fill of 3D meshes; dependent columns make the matrix semidefinite, where it
  // fails and the simplicial LDLT takes over.
  ++factorizations;
  if (free.size() >= kSupernodalFromColumns) {
    Eigen::CholmodSupernodalLLT<SparseMatrix> llt;
    llt.cholmod().print = 0;  // a failure is handled below, not printed on standard output
    llt.compute(normal);
    if (llt.info() == Eigen::Success) {
      Vector z = Refined(llt, sub, b, refinement_steps);
      if (z.allFinite()) return z;
    }
  }
  Eigen::SimplicialLDLT<SparseMatrix> ldlt(normal);
  if (ldlt.info() == Eigen::Success) {
    Vector z = Refined(ldlt, sub, b, refinement_steps);
    if (z.allFinite()) return z;
  }
  // Dependent columns (an unidentifiable combination of springs): the normal matrix is
  // singular. A tiny ridge on its unit diagonal picks the smallest solution among the equal
  // ones; SolveNnls then reports the round as not converged if it is not accurate.
  SparseMatrix identity(normal.rows(), normal.cols());
  identity.setIdentity();
  Eigen::SimplicialLDLT<SparseMatrix> ridge(normal + kRidge * identity);
  return Refined(ridge, sub, b, refinement_steps);
}

// The same on a dense matrix, whose normal matrix `normal` (of all columns) is formed once:
// each round only picks its rows and columns of the free set.
Vector SolveOn(const Matrix& a, const Matrix& normal, const Vector& b, const std::vector<int>& free,
               int refinement_steps, int& factorizations) {
  if (free.empty()) return Vector();
  const auto m = static_cast<Eigen::Index>(free.size());
  Matrix sub(a.rows(), m);
  Matrix normal_ff(m, m);
  for (Eigen::Index c = 0; c < m; ++c) {
    sub.col(c) = a.col(free[static_cast<std::size_t>(c)]);
    for (Eigen::Index r = 0; r < m; ++r)
      normal_ff(r, c) =
          normal(free[static_cast<std::size_t>(r)], free[static_cast<std::size_t>(c)]);
  }
  ++factorizations;
  // Eigen's dense LDLT pivots and passes a zero pivot as a pseudo-inverse rather than
  // failing: a pivot at round-off of the unit diagonal counts as failure here, as in the
  // sparse path, so that the ridge takes over.
  Eigen::LDLT<Matrix> ldlt(normal_ff);
  if (ldlt.info() == Eigen::Success && ldlt.vectorD().cwiseAbs().minCoeff() > kSingularUnitPivot) {
    Vector z = Refined(ldlt, sub, b, refinement_steps);
    if (z.allFinite()) return z;
  }
  Eigen::LDLT<Matrix> ridge(normal_ff + kRidge * Matrix::Identity(m, m));
  return Refined(ridge, sub, b, refinement_steps);
}

// Unit-norm column scaling: the weights of short and long springs, or of springs stretched a
// lot and a little, then sit on one scale for the tolerances and the solver. 0 for columns
// not usable.
template <class MatrixType>
Vector UnitColumnScale(const MatrixType& a, const std::vector<bool>& usable) {
  Vector scale = Vector::Zero(a.cols());
  for (Eigen::Index j = 0; j < a.cols(); ++j) {
    const double norm = a.col(j).norm();
    if (usable[static_cast<std::size_t>(j)] && norm > 0.0) scale[j] = 1.0 / norm;
  }
  return scale;
}

// The block principal pivoting on the scaled matrix `as`; `solve_on(free)` solves the
// unconstrained problem on a free set.
template <class MatrixType, class SolveOnFree>
NnlsResult Pivot(const MatrixType& as, const Vector& b, const Vector& scale,
                 const NnlsOptions& options, Interruption* interruption, SolveOnFree&& solve_on) {
  const auto n = static_cast<int>(as.cols());
  NnlsResult result;
  if (n == 0) {
    result.converged = true;
    result.residual_norm = b.norm();
    return result;
  }
  const Vector atb = as.transpose() * b;
  double atb_max = 0.0;
  for (Eigen::Index j = 0; j < atb.size(); ++j) atb_max = std::max(atb_max, std::abs(atb[j]));
  const double gradient_tolerance = options.tolerance * std::max(atb_max, 1e-300);

  std::vector<bool> in_free(n, false);
  for (int j = 0; j < n; ++j) in_free[j] = scale[j] > 0.0;  // start with every usable column free
  const int max_iterations =
      options.max_iterations > 0 ? options.max_iterations : std::min(10 + 3 * n, kDefaultRounds);

  Vector x = Vector::Zero(n);
  int fewest_violations = n + 1;
  int full_exchanges_left = options.full_exchange_budget;
  for (result.iterations = 1; result.iterations <= max_iterations; ++result.iterations) {
    ThrowIfInterrupted(interruption);
    std::vector<int> free;
    for (int j = 0; j < n; ++j) {
      if (in_free[j]) free.push_back(j);
    }
    const Vector z = solve_on(free, result.factorizations);
    x.setZero();
    for (std::size_t c = 0; c < free.size(); ++c) x[free[c]] = z[static_cast<Eigen::Index>(c)];
    const Vector gradient = as.transpose() * (as * x - b);  // of |A x - b|^2 / 2
    const double x_tolerance = options.tolerance * std::max(x.cwiseAbs().maxCoeff(), 1e-300);

    std::vector<int> violating;
    for (int j = 0; j < n; ++j) {
      if (scale[j] == 0.0) continue;
      if (in_free[j] ? x[j] < -x_tolerance : gradient[j] < -gradient_tolerance)
        violating.push_back(j);
    }
    if (violating.empty()) {
      // Optimal only if the solve on F was accurate: finite, and the gradient vanishing on F
      // (a ridge-regularised solve of dependent columns may not meet this).
      bool accurate = x.allFinite();
      for (int j = 0; j < n && accurate; ++j) {
        if (in_free[j])
          accurate =
              std::abs(gradient[j]) <= std::max(gradient_tolerance, kSolveAccuracy * atb_max);
      }
      result.converged = accurate;
      break;
    }
    const int count = static_cast<int>(violating.size());
    if (count < fewest_violations) {
      fewest_violations = count;
      full_exchanges_left = options.full_exchange_budget;
      for (const int j : violating) in_free[j] = !in_free[j];
    } else if (full_exchanges_left > 0) {
      --full_exchanges_left;
      for (const int j : violating) in_free[j] = !in_free[j];
    } else {
      in_free[violating.back()] = !in_free[violating.back()];  // Murty's rule: finite
    }
  }
  result.iterations = std::min(result.iterations, max_iterations);
  // Feasible whatever happened: a negative left by an unconverged run is clipped.
  for (Eigen::Index j = 0; j < x.size(); ++j)
    x[j] = std::isfinite(x[j]) ? std::max(x[j], 0.0) : 0.0;
  result.residual_norm = (as * x - b).norm();
  result.x = scale.cwiseProduct(x);
  return result;
}

}  // namespace

void NnlsOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  check.Require(max_iterations >= 0, "max_iterations", max_iterations,
                "value >= 0 (0: min(10 + 3n, 100))");
  check.Require(InOpenUnit(tolerance), "tolerance", tolerance, "0 < value < 1");
  check.Require(refinement_steps >= 0 && refinement_steps <= 100, "refinement_steps",
                refinement_steps, "0 <= value <= 100");
  check.Require(full_exchange_budget >= 0, "full_exchange_budget", full_exchange_budget,
                "value >= 0");
}

NnlsResult SolveNnls(const SparseMatrix& a, const Vector& b, const std::vector<bool>& usable,
                     const NnlsOptions& options, Interruption* interruption) {
  options.Validate();
  const Vector scale = UnitColumnScale(a, usable);
  const SparseMatrix as = a * scale.asDiagonal();
  return Pivot(as, b, scale, options, interruption,
               [&](const std::vector<int>& free, int& factorizations) {
                 return SolveOn(as, b, free, options.refinement_steps, factorizations);
               });
}

NnlsResult SolveDenseNnls(const Matrix& a, const Vector& b, const std::vector<bool>& usable,
                          const NnlsOptions& options) {
  options.Validate();
  const Vector scale = UnitColumnScale(a, usable);
  const Matrix as = a * scale.asDiagonal();
  const Matrix normal = as.transpose() * as;
  return Pivot(as, b, scale, options, nullptr,
               [&](const std::vector<int>& free, int& factorizations) {
                 return SolveOn(as, normal, b, free, options.refinement_steps, factorizations);
               });
}

}  // namespace springfit
