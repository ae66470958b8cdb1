#include "engine/linalg/symmetric_system.h"

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

#include "engine/linalg/supernodal_cholesky.h"

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
  sparse_work_ = sparse_;
  diagonal_slot_.resize(n);
  for (int i = 0; i < n; ++i) diagonal_slot_[i] = SparseSlot(i, i);
  // The banded backend keeps the pattern only for the pivot count (CountPivots): its
  // simplicial LDLT is analysed when first needed.
  if (backend_ != Backend::kBanded) AnalyseSparse();
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

double SymmetricSystem::Bytes() const {
  const auto sparse_bytes = [](const Eigen::SparseMatrix<double>& m) {
    return 12.0 * static_cast<double>(m.nonZeros()) + 4.0 * static_cast<double>(m.outerSize() + 1);
  };
  double bytes = 8.0 * static_cast<double>(band_.size() + band_factor_.size() + scale_.size()) +
                 4.0 * static_cast<double>(diagonal_slot_.size()) + sparse_bytes(sparse_) +
                 sparse_bytes(sparse_work_);
  // (L's values and row indices; D, the permutation and its inverse, the elimination tree)
  if (sldlt_)
    bytes += 12.0 * static_cast<double>(sldlt_->FactorEntries()) + 28.0 * static_cast<double>(n_);
  if (supernodal_) bytes += supernodal_->FactorBytes();
  return bytes;
}

SymmetricSystem::SymmetricSystem() = default;
SymmetricSystem::~SymmetricSystem() = default;

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
  // (a banded system analyses its counting pattern again when it first counts)
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
  return SparseSlot(row, col);
}

int SymmetricSystem::SparseSlot(int row, int col) const {
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
  used_sldlt_ = false;
  if (n_ == 0) {
    // Nothing free: trivially positive definite (LAPACK rejects order 0 leading dimensions).
    f.positive_definite = true;
    return f;
  }
  ComputeScaling();
  const auto pivots_of = [&](const auto& pivot, bool factorised) {
    if (!factorised) {
      f.min_pivot = -1.0;  // stopped at a non-positive pivot
      return;
    }
    for (int i = 0; i < n_; ++i) {
      f.min_pivot = std::min(f.min_pivot, pivot(i));
      if (pivot(i) <= tolerance) ++f.small_pivots;
    }
    f.positive_definite = f.small_pivots == 0;
  };
  // (A positive-definite factorisation is kept even when counting: the FEM solver reuses its
  // rest factor, which CHOLMOD's supernodal one makes fast.)
  if (backend_ == Backend::kBanded) {
    const int width = bandwidth_ + 1;
    band_factor_.resize(width, n_);  // no-op once sized (copies of a system start without it)
    for (int c = 0; c < n_; ++c) {
      const int rows = std::min(width, n_ - c);
      for (int k = 0; k < rows; ++k) band_factor_(k, c) = scale_[c + k] * band_(k, c) * scale_[c];
      band_factor_(0, c) += shift;
    }
    int info = 0;
    dpbtf2_("L", &n_, &bandwidth_, band_factor_.data(), &width, &info, 1);
    pivots_of([&](int i) { return band_factor_(0, i) * band_factor_(0, i); }, info == 0);
  } else {
    ScaleIntoWork(shift);
    if (backend_ == Backend::kSupernodal) {
      const bool factorised = supernodal_->Factorize(
          sparse_work_.outerIndexPtr(), sparse_work_.innerIndexPtr(), sparse_work_.valuePtr());
      const Vector pivots = factorised ? supernodal_->Pivots() : Vector();
      pivots_of([&](int i) { return pivots[i]; }, factorised);
    } else {
      f = CountPivots(shift, tolerance, /*scaled=*/true);  // Eigen's LDLT is the factorisation
      if (f.positive_definite || !count_pivots) return f;
      f.small_pivots = CountEigenvaluesBelow(shift, tolerance);
      f.positive_definite = f.small_pivots == 0;
      return f;
    }
  }
  if (f.positive_definite || !count_pivots) return f;
  // Singular or indefinite, and the small eigenvalues must be counted: by the one counter
  // every backend shares, so that a mechanism's mode count does not depend on the backend.
  // This leaves no factorisation for Solve(): a count is asked for only where no solve
  // follows.
  f.small_pivots = CountEigenvaluesBelow(shift, tolerance);
  f.positive_definite = f.small_pivots == 0;
  return f;
}

void SymmetricSystem::ScaleIntoWork(double shift) {
  const int* outer = sparse_.outerIndexPtr();
  const int* inner = sparse_.innerIndexPtr();
  double* w = sparse_work_.valuePtr();
  for (int c = 0; c < n_; ++c) {
    for (int p = outer[c]; p < outer[c + 1]; ++p) {
      const int r = inner[p];
      const double a = backend_ == Backend::kBanded ? band_(r - c, c) : values_[p];
      w[p] = scale_[r] * a * scale_[c];
    }
  }
  for (int i = 0; i < n_; ++i) w[diagonal_slot_[i]] += shift;
}

SymmetricSystem::Factorization SymmetricSystem::CountPivots(double shift, double tolerance,
                                                            bool scaled) {
  if (!scaled) ScaleIntoWork(shift);
  if (!sldlt_) {
    sldlt_ = std::make_unique<SparseLdlt>();
    sldlt_->analyzePattern(sparse_work_);
  }
  sldlt_->factorize(sparse_work_);
  used_sldlt_ = true;
  Factorization f;
  if (sldlt_->info() != Eigen::Success) {
    // An exactly zero pivot stops Eigen's factorisation.
    f.min_pivot = 0.0;
    return f;
  }
  const Vector& d = sldlt_->vectorD();
  f.min_pivot = std::numeric_limits<double>::infinity();
  for (int i = 0; i < n_; ++i) {
    f.min_pivot = std::min(f.min_pivot, d[i]);
    if (d[i] <= tolerance) ++f.small_pivots;
  }
  f.positive_definite = f.small_pivots == 0;
  return f;
}

int SymmetricSystem::CountEigenvaluesBelow(double shift, double tolerance) {
  // Sylvester's law of inertia: S A S + shift I - tolerance I = L D L^T has as many negative
  // pivots as S A S + shift I has eigenvalues below `tolerance`, whatever the ordering and
  // however the small eigenvalues' vectors spread over the unknowns. (Counting the pivots of
  // S A S + shift I below the tolerance instead is not a count of anything: a pivot is a ratio
  // of leading minors, so a mode completed by the last of its unknowns can show as a
  // moderately small pivot, and a nearly singular leading block as a small one followed by a
  // large one.) An exactly zero pivot stops the factorisation: the shift is moved by a
  // relative 1e-6 and tried again, which cannot change a count that means anything.
  if (n_ == 0) return 0;
  ComputeScaling();
  double offset = shift - tolerance;
  for (int attempt = 0; attempt < 4; ++attempt) {
    ScaleIntoWork(offset);
    if (!sldlt_) {
      sldlt_ = std::make_unique<SparseLdlt>();
      sldlt_->analyzePattern(sparse_work_);
    }
    sldlt_->factorize(sparse_work_);
    // The factorisation is of the shifted matrix: no Solve() may use it.
    used_sldlt_ = false;
    if (sldlt_->info() == Eigen::Success) {
      const Vector& d = sldlt_->vectorD();
      int negative = 0;
      for (int i = 0; i < n_; ++i) negative += d[i] < 0.0 ? 1 : 0;
      return negative;
    }
    offset -= 1e-6 * tolerance;
  }
  return n_;  // never seen: four exact zero pivots in a row
}

SymmetricSystem::Factorization SymmetricSystem::FactorizeIndefinite(double shift) {
  if (n_ == 0) return Factorize(shift, 0.0, false);
  ComputeScaling();
  return CountPivots(shift, 0.0, /*scaled=*/false);
}

void SymmetricSystem::Solve(Vector& b) const {
  if (n_ == 0) return;
  b.array() *= scale_.array();
  if (used_sldlt_) {
    b = sldlt_->solve(b);
  } else if (backend_ == Backend::kBanded) {
    const int width = bandwidth_ + 1, one = 1;
    int info = 0;
    dpbtrs_("L", &n_, &bandwidth_, &one, band_factor_.data(), &width, b.data(), &n_, &info, 1);
  } else {
    supernodal_->Solve(b);
  }
  b.array() *= scale_.array();
}

}  // namespace springfit
