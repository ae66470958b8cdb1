#include "engine/symmetric_system.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstddef>
#include <limits>

// LAPACK (Fortran; the trailing arguments are the hidden lengths of the character arguments).
extern "C" {
void dpbtf2_(const char* uplo, const int* n, const int* kd, double* ab, const int* ldab, int* info,
             std::size_t uplo_len);
void dpbtrs_(const char* uplo, const int* n, const int* kd, const int* nrhs, const double* ab,
             const int* ldab, double* b, const int* ldb, int* info, std::size_t uplo_len);
}

namespace springfit {

SymmetricSystem::SymmetricSystem(int n, std::vector<std::pair<int, int>> lower, Backend backend)
    : n_(n), backend_(backend), scale_(Vector::Ones(n)) {
  for (int i = 0; i < n; ++i) lower.emplace_back(i, i);
  if (backend_ == Backend::kBanded) {
    for (const auto& [r, c] : lower) {
      assert(r >= c);
      bandwidth_ = std::max(bandwidth_, r - c);
    }
    band_ = Matrix::Zero(bandwidth_ + 1, n);
    band_factor_ = band_;
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
  AnalyseSparse();
}

void SymmetricSystem::AnalyseSparse() {
  if (backend_ == Backend::kSupernodal) {
    supernodal_ = std::make_unique<SupernodalCholesky>(n_, sparse_work_.outerIndexPtr(),
                                                       sparse_work_.innerIndexPtr());
    return;
  }
  sldlt_ = std::make_unique<SparseLdlt>();
  sldlt_->analyzePattern(sparse_work_);
}

SymmetricSystem::SymmetricSystem(const SymmetricSystem& other)
    : n_(other.n_),
      backend_(other.backend_),
      scale_(other.scale_),
      bandwidth_(other.bandwidth_),
      band_(other.band_),
      sparse_(other.sparse_),
      sparse_work_(other.sparse_work_),
      diagonal_slot_(other.diagonal_slot_) {
  RebindValues();
  if (other.sldlt_ || other.supernodal_) AnalyseSparse();
}

SymmetricSystem& SymmetricSystem::operator=(const SymmetricSystem& other) {
  if (this != &other) *this = SymmetricSystem(other);
  return *this;
}

SymmetricSystem::SymmetricSystem(SymmetricSystem&& other) noexcept
    : n_(other.n_),
      backend_(other.backend_),
      scale_(std::move(other.scale_)),
      bandwidth_(other.bandwidth_),
      band_(std::move(other.band_)),
      band_factor_(std::move(other.band_factor_)),
      sparse_(std::move(other.sparse_)),
      sparse_work_(std::move(other.sparse_work_)),
      diagonal_slot_(std::move(other.diagonal_slot_)),
      sldlt_(std::move(other.sldlt_)),
      supernodal_(std::move(other.supernodal_)) {
  RebindValues();
}

SymmetricSystem& SymmetricSystem::operator=(SymmetricSystem&& other) noexcept {
  n_ = other.n_;
  backend_ = other.backend_;
  scale_ = std::move(other.scale_);
  bandwidth_ = other.bandwidth_;
  band_ = std::move(other.band_);
  band_factor_ = std::move(other.band_factor_);
  used_ldlt_ = false;
  sparse_ = std::move(other.sparse_);
  sparse_work_ = std::move(other.sparse_work_);
  diagonal_slot_ = std::move(other.diagonal_slot_);
  sldlt_ = std::move(other.sldlt_);
  supernodal_ = std::move(other.supernodal_);
  used_sldlt_ = false;
  RebindValues();
  return *this;
}

int SymmetricSystem::Slot(int row, int col) const {
  assert(row >= col && row < n_);
  if (backend_ == Backend::kBanded) {
    assert(row - col <= bandwidth_);
    return (row - col) + col * (bandwidth_ + 1);
  }
  const int* inner = sparse_.innerIndexPtr();
  const int begin = sparse_.outerIndexPtr()[col];
  const int end = sparse_.outerIndexPtr()[col + 1];
  const int* it = std::lower_bound(inner + begin, inner + end, row);
  assert(it != inner + end && *it == row);
  return static_cast<int>(it - inner);
}

void SymmetricSystem::SetZero() {
  if (backend_ == Backend::kBanded) {
    band_.setZero();
  } else {
    std::fill(sparse_.valuePtr(), sparse_.valuePtr() + sparse_.nonZeros(), 0.0);
  }
}

Matrix SymmetricSystem::BandToDense(const Matrix& band) const {
  Matrix a = Matrix::Zero(n_, n_);
  for (int c = 0; c < n_; ++c) {
    for (int r = c; r <= std::min(n_ - 1, c + bandwidth_); ++r) a(r, c) = band(r - c, c);
  }
  return a;
}

Matrix SymmetricSystem::ToDense() const {
  Matrix a = backend_ == Backend::kBanded ? BandToDense(band_) : Matrix(Eigen::MatrixXd(sparse_));
  a.triangularView<Eigen::StrictlyUpper>() = a.transpose();
  return a;
}

void SymmetricSystem::ComputeScaling() {
  for (int i = 0; i < n_; ++i) {
    const double d = backend_ == Backend::kBanded ? band_(0, i) : values_[diagonal_slot_[i]];
    // A zero or negative diagonal has no scale; 1 keeps it visible as a small pivot.
    scale_[i] = d > 0.0 ? 1.0 / std::sqrt(d) : 1.0;
  }
}

SymmetricSystem::Factorization SymmetricSystem::Factorize(double shift, double tolerance,
                                                          bool count_pivots) {
  Factorization f;
  f.min_pivot = std::numeric_limits<double>::infinity();
  if (n_ ==
      0) {  // nothing free: trivially positive definite (LAPACK rejects order 0 leading dimensions)
    f.positive_definite = true;
    return f;
  }
  ComputeScaling();
  if (backend_ == Backend::kBanded) {
    const int width = bandwidth_ + 1;
    const auto scale_into_factor = [&] {
      band_factor_.resize(width, n_);  // no-op once sized (copies of a system start without it)
      for (int c = 0; c < n_; ++c) {
        const int rows = std::min(width, n_ - c);
        for (int k = 0; k < rows; ++k) band_factor_(k, c) = scale_[c + k] * band_(k, c) * scale_[c];
        band_factor_(0, c) += shift;
      }
    };
    scale_into_factor();
    used_ldlt_ = false;
    int info = 0;
    dpbtf2_("L", &n_, &bandwidth_, band_factor_.data(), &width, &info, 1);
    if (info == 0) {
      for (int i = 0; i < n_; ++i) {
        const double pivot = band_factor_(0, i) * band_factor_(0, i);
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
    scale_into_factor();  // dpbtf2 left the columns before the failed pivot factored
    ldlt_.compute(BandToDense(band_factor_));
    used_ldlt_ = true;
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
  if (backend_ == Backend::kSupernodal) {
    used_sldlt_ = false;
    if (supernodal_->Factorize(sparse_work_.outerIndexPtr(), sparse_work_.innerIndexPtr(), w)) {
      const Vector pivots = supernodal_->Pivots();
      for (int i = 0; i < n_; ++i) {
        f.min_pivot = std::min(f.min_pivot, pivots[i]);
        if (pivots[i] <= tolerance) ++f.small_pivots;
      }
      f.positive_definite = f.small_pivots == 0;
      return f;
    }
    if (!count_pivots) {
      f.min_pivot = -1.0;
      return f;
    }
    // Indefinite beyond the shift: the simplicial LDLT still counts the pivots.
    if (!sldlt_) {
      sldlt_ = std::make_unique<SparseLdlt>();
      sldlt_->analyzePattern(sparse_work_);
    }
    used_sldlt_ = true;
  }
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
  if (n_ == 0) return;
  b.array() *= scale_.array();
  if (backend_ == Backend::kBanded) {
    if (used_ldlt_) {
      b = ldlt_.solve(b);
    } else {
      const int width = bandwidth_ + 1, one = 1;
      int info = 0;
      dpbtrs_("L", &n_, &bandwidth_, &one, band_factor_.data(), &width, b.data(), &n_, &info, 1);
    }
  } else if (backend_ == Backend::kSupernodal && !used_sldlt_) {
    supernodal_->Solve(b);
  } else {
    b = sldlt_->solve(b);
  }
  b.array() *= scale_.array();
}

}  // namespace springfit
