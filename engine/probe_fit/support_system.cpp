#include "engine/probe_fit/support_system.h"

#include <Eigen/Cholesky>

#include "engine/linalg/blocked_triangular_solve.h"

namespace springfit::response {
namespace {

// A support's system is singular (the support leaves a rigid motion free) when its smallest
// pivot is below this fraction of its largest: round-off of a zero pivot in a
// double-precision factorisation, not a soft mode of tissue.
constexpr double kSingularPivotRatio = 1e-14;
// The same bound on the diagonal of L (LL^T), which holds the pivots' square roots.
constexpr double kSingularDiagonalRatio = 1e-7;

}  // namespace

SupportSystem::SupportSystem(int dimension, const std::vector<bool>& constrained)
    : dimension_(dimension), constrained_(constrained) {
  const int d = dimension;
  free_index_.assign(constrained.size() * static_cast<std::size_t>(d), -1);
  for (std::size_t node = 0; node < constrained.size(); ++node) {
    if (constrained[node]) continue;
    for (int c = 0; c < d; ++c) {
      const int dof = d * static_cast<int>(node) + c;
      free_index_[static_cast<std::size_t>(dof)] = static_cast<int>(free_dofs_.size());
      free_dofs_.push_back(dof);
    }
  }
}

SupportSystem SupportSystem::OfDofs(int dimension, const std::vector<bool>& held_dofs) {
  const auto d = static_cast<std::size_t>(dimension);
  std::vector<bool> nodes(held_dofs.size() / d, false);
  SupportSystem system(dimension, nodes);
  system.free_dofs_.clear();
  for (std::size_t dof = 0; dof < held_dofs.size(); ++dof) {
    if (held_dofs[dof]) {
      system.constrained_[dof / d] = true;
      system.free_index_[dof] = -1;
      continue;
    }
    system.free_index_[dof] = static_cast<int>(system.free_dofs_.size());
    system.free_dofs_.push_back(static_cast<int>(dof));
  }
  return system;
}

bool SupportSystem::Factorize(const SparseMatrix& full) {
  full_ = full;
  const int n = free_dofs();
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(static_cast<std::size_t>(full.nonZeros()));
  for (int col = 0; col < full.outerSize(); ++col) {
    const int c = free_index_[static_cast<std::size_t>(col)];
    if (c < 0) continue;
    for (SparseMatrix::InnerIterator it(full, col); it; ++it) {
      const int r = free_index_[static_cast<std::size_t>(it.row())];
      if (r >= c) t.emplace_back(r, c, it.value());
    }
  }
  restricted_.resize(n, n);
  restricted_.setFromTriplets(t.begin(), t.end());
  llt_.reset();
  supernodal_.reset();
  if (n == 0) return false;
  // A positive pivot far below the largest is a mechanism as well (round-off of a singular
  // matrix): the same unit-free test as the equilibrium solver's, on the diagonal of L.
  if (dimension_ == 3 && n >= kSupernodalMinDofs3d) {
    restricted_.makeCompressed();
    supernodal_ = std::make_unique<SupernodalCholesky>(n, restricted_.outerIndexPtr(),
                                                       restricted_.innerIndexPtr());
    if (!supernodal_->Factorize(restricted_.outerIndexPtr(), restricted_.innerIndexPtr(),
                                restricted_.valuePtr()))
      return false;
    const Vector pivots = supernodal_->Pivots();
    return pivots.minCoeff() > kSingularPivotRatio * pivots.maxCoeff();
  }
  llt_ = std::make_unique<Llt>();
  llt_->compute(restricted_);
  if (llt_->info() != Eigen::Success) return false;
  const Vector diagonal = llt_->matrixL().nestedExpression().diagonal();
  const double largest = diagonal.cwiseAbs().maxCoeff();
  return diagonal.minCoeff() > kSingularDiagonalRatio * largest;
}

Vector SupportSystem::Gather(const Vector& full) const {
  Vector free(free_dofs());
  for (int i = 0; i < free_dofs(); ++i) free[i] = full[free_dofs_[static_cast<std::size_t>(i)]];
  return free;
}

Vector SupportSystem::Scatter(const Vector& free, const Vector& prescribed) const {
  Vector full = prescribed.size() == 0 ? Vector::Zero(static_cast<Eigen::Index>(free_index_.size()))
                                       : prescribed;
  for (int i = 0; i < free_dofs(); ++i) full[free_dofs_[static_cast<std::size_t>(i)]] = free[i];
  return full;
}

Vector SupportSystem::RightHandSide(const Vector& force, const Vector& prescribed) const {
  if (prescribed.size() == 0 || prescribed.isZero(0.0)) return Gather(force);
  return Gather(force - full_ * prescribed);
}

void SupportSystem::Solve(Vector& b) const {
  if (supernodal_)
    supernodal_->Solve(b);
  else
    b = llt_->solve(b);
}

void SupportSystem::SolveColumns(Matrix& b) const {
  if (supernodal_) {
    supernodal_->SolveColumns(b);
    return;
  }
  // Eigen's factor: compressed columns, rows ascending, the diagonal first in each.
  const SparseMatrix& l = llt_->matrixL().nestedExpression();
  const int* outer = l.outerIndexPtr();
  const auto column = [&](Eigen::Index j) {
    const int first = outer[j];
    return FactorColumn{l.innerIndexPtr() + first, l.valuePtr() + first, outer[j + 1] - first};
  };
  RowBlock y = llt_->permutationP() * b;
  SolveWithCholeskyFactor(l.cols(), column, y);
  b = llt_->permutationPinv() * y;
}

Vector SupportSystem::Displacement(const Vector& force, const Vector& prescribed) const {
  Vector free = RightHandSide(force, prescribed);
  Solve(free);
  return Scatter(free, prescribed);  // (every free entry overwritten)
}

Vector SupportSystem::Multiply(const Vector& x) const {
  return restricted_.selfadjointView<Eigen::Lower>() * x;
}

Matrix SupportSystem::Compliance() const {
  const int n = free_dofs();
  Matrix c = Matrix::Identity(n, n);
  SolveColumns(c);
  return c;
}

}  // namespace springfit::response
