#include "engine/direct/nnls.h"

#include <Eigen/CholmodSupport>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>

namespace springfit {
namespace {

// Below this many columns the simplicial factorisation is faster (bench/direct_bench: 4 ms
// against 6 ms on grid3d-4x4x4's 465 columns; 2.5 s against 10.7 s on 12x12x12's 18,777).
constexpr std::size_t kSupernodalFromColumns = 2000;

// The columns of `a` listed in `columns`, as a new matrix.
SparseMatrix Columns(const SparseMatrix& a, const std::vector<int>& columns) {
  SparseMatrix sub(a.rows(), static_cast<Eigen::Index>(columns.size()));
  Eigen::VectorXi sizes(static_cast<Eigen::Index>(columns.size()));
  for (std::size_t c = 0; c < columns.size(); ++c) {
    sizes[static_cast<Eigen::Index>(c)] = static_cast<int>(a.col(columns[c]).nonZeros());
  }
  sub.reserve(sizes);
  for (std::size_t c = 0; c < columns.size(); ++c) {
    for (SparseMatrix::InnerIterator it(a, columns[c]); it; ++it) {
      sub.insert(it.row(), static_cast<Eigen::Index>(c)) = it.value();
    }
  }
  sub.makeCompressed();
  return sub;
}

// The least-squares solution on the columns `free` (unconstrained), refined.
Vector SolveOn(const SparseMatrix& a, const Vector& b, const std::vector<int>& free, int refinement_steps,
               int& factorizations) {
  if (free.empty()) return Vector();
  const SparseMatrix sub = Columns(a, free);
  const SparseMatrix normal = sub.transpose() * sub;
  // CHOLMOD's supernodal Cholesky (dense BLAS blocks) is many times faster than a simplicial
  // one on the fill of 3D meshes; dependent columns make the matrix semidefinite, where it
  // fails and the simplicial LDLT takes over.
  auto refine = [&](const auto& factor) {
    Vector z = factor.solve(sub.transpose() * b);
    for (int step = 0; step < refinement_steps; ++step) {
      const Vector r = b - sub * z;
      z += factor.solve(sub.transpose() * r);
    }
    return z;
  };
  ++factorizations;
  if (free.size() >= kSupernodalFromColumns) {
    Eigen::CholmodSupernodalLLT<SparseMatrix> llt(normal);
    if (llt.info() == Eigen::Success) return refine(llt);
  }
  Eigen::SimplicialLDLT<SparseMatrix> ldlt(normal);
  return refine(ldlt);
}

}  // namespace

NnlsResult SolveNnls(const SparseMatrix& a, const Vector& b, const std::vector<bool>& usable,
                     const NnlsOptions& options) {
  const int n = static_cast<int>(a.cols());
  // Scale every column to unit norm: the weights of short and long springs, or of springs
  // stretched a lot and a little, then sit on one scale for the tolerances and the solver.
  Vector scale = Vector::Zero(n);
  for (int j = 0; j < n; ++j) {
    const double norm = a.col(j).norm();
    if (usable[j] && norm > 0.0) scale[j] = 1.0 / norm;
  }
  const SparseMatrix as = a * scale.asDiagonal();
  const Vector atb = as.transpose() * b;
  const double gradient_tolerance = options.tolerance * std::max(atb.cwiseAbs().maxCoeff(), 1e-300);

  std::vector<bool> in_free(n, false);
  for (int j = 0; j < n; ++j) in_free[j] = scale[j] > 0.0;  // start with every usable column free
  const int max_iterations = options.max_iterations > 0 ? options.max_iterations : 10 + 3 * n;

  NnlsResult result;
  Vector x = Vector::Zero(n);
  int fewest_violations = n + 1;
  int full_exchanges_left = options.full_exchange_budget;
  for (result.iterations = 1; result.iterations <= max_iterations; ++result.iterations) {
    std::vector<int> free;
    for (int j = 0; j < n; ++j) {
      if (in_free[j]) free.push_back(j);
    }
    const Vector z = SolveOn(as, b, free, options.refinement_steps, result.factorizations);
    x.setZero();
    for (std::size_t c = 0; c < free.size(); ++c) x[free[c]] = z[static_cast<Eigen::Index>(c)];
    const Vector gradient = as.transpose() * (as * x - b);  // of |A x - b|^2 / 2
    const double x_tolerance = options.tolerance * std::max(x.cwiseAbs().maxCoeff(), 1e-300);

    std::vector<int> violating;
    for (int j = 0; j < n; ++j) {
      if (scale[j] == 0.0) continue;
      if (in_free[j] ? x[j] < -x_tolerance : gradient[j] < -gradient_tolerance) violating.push_back(j);
    }
    if (violating.empty()) {
      result.converged = true;
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
  x = x.cwiseMax(0.0);
  result.residual_norm = (as * x - b).norm();
  result.x = scale.cwiseProduct(x);
  return result;
}

}  // namespace springfit
