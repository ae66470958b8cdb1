#include "engine/symmetric_system.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

namespace springfit {

SymmetricSystem::SymmetricSystem(int n, std::vector<std::pair<int, int>> lower, Backend backend)
    : n_(n), backend_(backend), scale_(Vector::Ones(n)) {
  for (int i = 0; i < n; ++i) lower.emplace_back(i, i);
  if (backend_ == Backend::kDense) {
    dense_ = Matrix::Zero(n, n);
    dense_work_ = Matrix::Zero(n, n);
    RebindValues();
    return;
  }
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(lower.size());
  for (const auto& [r, c] : lower) {
    assert(r >= c);
    triplets.emplace_back(r, c, 0.0);
  }
  sparse_.resize(n, n);
  sparse_.setFromTriplets(triplets.begin(), triplets.end());
  sparse_.makeCompressed();
  RebindValues();
  diagonal_slot_.resize(n);
  for (int i = 0; i < n; ++i) diagonal_slot_[i] = Slot(i, i);
  sparse_work_ = sparse_;
  sldlt_ = std::make_unique<SparseLdlt>();
  sldlt_->analyzePattern(sparse_work_);
}

SymmetricSystem::SymmetricSystem(const SymmetricSystem& other)
    : n_(other.n_),
      backend_(other.backend_),
      scale_(other.scale_),
      dense_(other.dense_),
      dense_work_(other.dense_work_),
      sparse_(other.sparse_),
      sparse_work_(other.sparse_work_),
      diagonal_slot_(other.diagonal_slot_) {
  RebindValues();
  if (other.sldlt_) {
    sldlt_ = std::make_unique<SparseLdlt>();
    sldlt_->analyzePattern(sparse_work_);
  }
}

SymmetricSystem& SymmetricSystem::operator=(const SymmetricSystem& other) {
  if (this != &other) *this = SymmetricSystem(other);
  return *this;
}

SymmetricSystem::SymmetricSystem(SymmetricSystem&& other) noexcept
    : n_(other.n_),
      backend_(other.backend_),
      scale_(std::move(other.scale_)),
      dense_(std::move(other.dense_)),
      dense_work_(std::move(other.dense_work_)),
      sparse_(std::move(other.sparse_)),
      sparse_work_(std::move(other.sparse_work_)),
      diagonal_slot_(std::move(other.diagonal_slot_)),
      sldlt_(std::move(other.sldlt_)) {
  RebindValues();
}

SymmetricSystem& SymmetricSystem::operator=(SymmetricSystem&& other) noexcept {
  n_ = other.n_;
  backend_ = other.backend_;
  scale_ = std::move(other.scale_);
  dense_ = std::move(other.dense_);
  dense_work_ = std::move(other.dense_work_);
  dense_used_ldlt_ = false;
  sparse_ = std::move(other.sparse_);
  sparse_work_ = std::move(other.sparse_work_);
  diagonal_slot_ = std::move(other.diagonal_slot_);
  sldlt_ = std::move(other.sldlt_);
  RebindValues();
  return *this;
}

int SymmetricSystem::Slot(int row, int col) const {
  assert(row >= col && row < n_);
  if (backend_ == Backend::kDense) return row + col * n_;
  const int* inner = sparse_.innerIndexPtr();
  const int begin = sparse_.outerIndexPtr()[col];
  const int end = sparse_.outerIndexPtr()[col + 1];
  const int* it = std::lower_bound(inner + begin, inner + end, row);
  assert(it != inner + end && *it == row);
  return static_cast<int>(it - inner);
}

void SymmetricSystem::SetZero() {
  if (backend_ == Backend::kDense) {
    dense_.setZero();
  } else {
    std::fill(sparse_.valuePtr(), sparse_.valuePtr() + sparse_.nonZeros(), 0.0);
  }
}

Matrix SymmetricSystem::ToDense() const {
  Matrix a = backend_ == Backend::kDense ? dense_ : Matrix(Eigen::MatrixXd(sparse_));
  a.triangularView<Eigen::StrictlyUpper>() = a.transpose();
  return a;
}

void SymmetricSystem::ComputeScaling() {
  for (int i = 0; i < n_; ++i) {
    const double d = backend_ == Backend::kDense ? dense_(i, i) : values_[diagonal_slot_[i]];
    // A zero or negative diagonal has no scale; 1 keeps it visible as a small pivot.
    scale_[i] = d > 0.0 ? 1.0 / std::sqrt(d) : 1.0;
  }
}

SymmetricSystem::Factorization SymmetricSystem::Factorize(double shift, double tolerance,
                                                          bool count_pivots) {
  ComputeScaling();
  Factorization f;
  f.min_pivot = std::numeric_limits<double>::infinity();
  if (backend_ == Backend::kDense) {
    // Scale the lower triangle only: that is all the factorisations read.
    const auto scaled_into = [&](Matrix& m) {
      for (int c = 0; c < n_; ++c) {
        for (int r = c; r < n_; ++r) m(r, c) = scale_[r] * dense_(r, c) * scale_[c];
        m(c, c) += shift;
      }
    };
    dense_factor_.resize(n_, n_);  // no-op once sized (copies of a system start without it)
    scaled_into(dense_factor_);
    dense_used_ldlt_ = false;
    if (Eigen::internal::llt_inplace<double, Eigen::Lower>::unblocked(dense_factor_) < 0) {
      const Matrix& l = dense_factor_;
      for (int i = 0; i < n_; ++i) {
        const double pivot = l(i, i) * l(i, i);
        f.min_pivot = std::min(f.min_pivot, pivot);
        if (pivot <= tolerance) ++f.small_pivots;
      }
      f.positive_definite = f.small_pivots == 0;
      return f;
    }
    if (!count_pivots) {
      f.min_pivot = -1.0;
      return f;
    }
    // Indefinite or singular beyond the shift: the pivoted LDLT still counts its pivots.
    scaled_into(dense_work_);
    ldlt_.compute(dense_work_);
    dense_used_ldlt_ = true;
    const Vector d = ldlt_.vectorD();
    for (int i = 0; i < n_; ++i) {
      f.min_pivot = std::min(f.min_pivot, d[i]);
      if (d[i] <= tolerance) ++f.small_pivots;
    }
    f.positive_definite = false;
    return f;
  }

  const int* outer = sparse_.outerIndexPtr();
  const int* inner = sparse_.innerIndexPtr();
  const double* a = sparse_.valuePtr();
  double* w = sparse_work_.valuePtr();
  for (int c = 0; c < n_; ++c) {
    for (int p = outer[c]; p < outer[c + 1]; ++p) w[p] = scale_[inner[p]] * a[p] * scale_[c];
  }
  for (int i = 0; i < n_; ++i) w[diagonal_slot_[i]] += shift;
  sldlt_->factorize(sparse_work_);
  if (sldlt_->info() != Eigen::Success) {
    // An exactly zero pivot stops Eigen's factorisation; with a positive shift this only
    // happens for a matrix far from positive definite.
    f.min_pivot = 0.0;
    f.small_pivots = n_;
    return f;
  }
  const Vector& d = sldlt_->vectorD();
  for (int i = 0; i < n_; ++i) {
    f.min_pivot = std::min(f.min_pivot, d[i]);
    if (d[i] <= tolerance) ++f.small_pivots;
  }
  f.positive_definite = f.small_pivots == 0;
  return f;
}

void SymmetricSystem::Solve(Vector& b) const {
  b.array() *= scale_.array();
  if (backend_ == Backend::kDense) {
    if (dense_used_ldlt_) {
      b = ldlt_.solve(b);
    } else {
      dense_factor_.triangularView<Eigen::Lower>().solveInPlace(b);
      dense_factor_.triangularView<Eigen::Lower>().transpose().solveInPlace(b);
    }
  } else {
    b = sldlt_->solve(b);
  }
  b.array() *= scale_.array();
}

}  // namespace springfit
