#include "engine/problem/support_system.h"

#include <algorithm>
#include <stdexcept>

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

SupportSystem::SupportSystem(int dimension, const std::vector<bool>& constrained,
                             const SupportSystem* base)
    : SupportSystem(dimension, constrained) {
  if (!base) return;
  base_ = base;
  for (int dof : free_dofs_) {
    const int b = base->free_index_[static_cast<std::size_t>(dof)];
    if (b < 0)
      throw std::invalid_argument(
          "SupportSystem: a bordered support frees a degree of freedom "
          "its base holds");
    base_index_.push_back(b);
  }
  for (std::size_t dof = 0; dof < free_index_.size(); ++dof)
    if (free_index_[dof] < 0 && base->free_index_[dof] >= 0)
      border_.push_back(base->free_index_[dof]);
}

namespace {

// Whether two matrices are the same, entry for entry (a cheap pass beside a factorisation).
bool SameMatrix(const SparseMatrix& a, const SparseMatrix& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols() || a.nonZeros() != b.nonZeros() ||
      !a.isCompressed() || !b.isCompressed())
    return false;
  const auto nnz = static_cast<std::size_t>(a.nonZeros());
  return std::equal(a.outerIndexPtr(), a.outerIndexPtr() + a.outerSize() + 1, b.outerIndexPtr()) &&
         std::equal(a.innerIndexPtr(), a.innerIndexPtr() + nnz, b.innerIndexPtr()) &&
         std::equal(a.valuePtr(), a.valuePtr() + nnz, b.valuePtr());
}

}  // namespace

bool SupportSystem::Factorize(const SparseMatrix& full) {
  bordered_ = false;
  if (base_ && base_->held_ && !base_->bordered_ && SameMatrix(full, base_->full_)) {
    full_ = SparseMatrix();
    restricted_ = SparseMatrix();
    llt_.reset();
    supernodal_.reset();
    return held_ = FactorizeBordered();
  }
  return held_ = FactorizeOwn(full);
}

// A principal submatrix of the base's positive definite K_ff: positive definite too, and so is
// the Schur complement.
bool SupportSystem::FactorizeBordered() {
  if (free_dofs() == 0) return false;
  const auto m = static_cast<Eigen::Index>(border_.size());
  border_solves_ = Matrix::Zero(base_->free_dofs(), m);
  for (Eigen::Index j = 0; j < m; ++j)
    border_solves_(border_[static_cast<std::size_t>(j)], j) = 1.0;
  base_->SolveColumns(border_solves_);
  Matrix schur(m, m);
  for (Eigen::Index i = 0; i < m; ++i)
    schur.row(i) = border_solves_.row(border_[static_cast<std::size_t>(i)]);
  schur_.compute(schur);
  if (schur_.info() != Eigen::Success) return false;
  bordered_ = true;
  return true;
}

void SupportSystem::SolveBordered(Matrix& b) const {
  // With u_c = 0 on the degrees of freedom held besides: K u = b + E mu on the base's free ones
  // and E^T u = 0, so u = w - Z S^-1 E^T w with w = K^-1 b, Z = K^-1 E and S = E^T Z.
  Matrix w = Matrix::Zero(base_->free_dofs(), b.cols());
  for (std::size_t i = 0; i < base_index_.size(); ++i)
    w.row(base_index_[i]) = b.row(static_cast<Eigen::Index>(i));
  base_->SolveColumns(w);
  Matrix t(static_cast<Eigen::Index>(border_.size()), b.cols());
  for (std::size_t j = 0; j < border_.size(); ++j)
    t.row(static_cast<Eigen::Index>(j)) = w.row(border_[j]);
  w.noalias() -= border_solves_ * schur_.solve(t);
  for (std::size_t i = 0; i < base_index_.size(); ++i)
    b.row(static_cast<Eigen::Index>(i)) = w.row(base_index_[i]);
}

bool SupportSystem::FactorizeOwn(const SparseMatrix& full) {
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
  return Gather(force - Full() * prescribed);
}

void SupportSystem::Solve(Vector& b) const {
  if (bordered_) {
    Matrix column = b;
    SolveBordered(column);
    b = column.col(0);
  } else if (supernodal_)
    supernodal_->Solve(b);
  else
    b = llt_->solve(b);
}

void SupportSystem::SolveColumns(Matrix& b) const {
  if (bordered_) {
    SolveBordered(b);
    return;
  }
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
  if (!bordered_) return restricted_.selfadjointView<Eigen::Lower>() * x;
  Vector on_base = Vector::Zero(base_->free_dofs());
  for (std::size_t i = 0; i < base_index_.size(); ++i)
    on_base[base_index_[i]] = x[static_cast<Eigen::Index>(i)];
  const Vector product = base_->Multiply(on_base);
  Vector y(free_dofs());
  for (std::size_t i = 0; i < base_index_.size(); ++i)
    y[static_cast<Eigen::Index>(i)] = product[base_index_[i]];
  return y;
}

}  // namespace springfit::response
