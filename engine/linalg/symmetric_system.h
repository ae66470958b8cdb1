// A symmetric linear system A x = b on a sparsity pattern fixed at construction, with one
// interface over a banded and a sparse factorisation.
//
// Callers assemble into `values()` through slots (positions of lower-triangle entries) that they
// look up once with Slot(); assembly then costs no search. Factorize() works on the
// Jacobi-scaled matrix S A S (S = diag(A)^-1/2): its pivots are unit-free, so one tolerance
// tells a healthy pivot from a mechanism whatever the stiffness scale or spread (a scene with
// stiffness ratios of 1e8 has raw pivot ratios far below round-off of a mechanism's). The
// sparse backend does its symbolic analysis (AMD ordering, elimination tree) once, here, and
// reuses it for every factorisation. The banded backend stores the lower band of the pattern
// (LAPACK's band storage, as wide as the pattern's farthest entry from the diagonal) and
// factorises it with LAPACK's unblocked band Cholesky: for the small scenes it serves, a grid
// numbered row by row, the band is a third of the matrix and so is the work.
//
// Counting the small eigenvalues of a singular or indefinite matrix (a mechanism's modes) is
// done the same way whatever the backend: the inertia of a simplicial LDLT (AMD ordering) of
// the same scaled matrix shifted down by the tolerance (CountEigenvaluesBelow). A count that
// depended on the backend would make the graded mechanism penalty, hence a search's
// trajectory, depend on a size threshold. Counting small pivots instead would miss modes and
// invent others (a pivot is a ratio of leading minors, not an eigenvalue);
// tests/engine/linalg/numerics_stress_test.cpp checks the count against a dense eigensolver.
//
// Not thread-safe; copy one per thread.
#pragma once

#include <memory>
#include <utility>
#include <vector>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "engine/linalg/linalg.h"

namespace springfit {

class SupernodalCholesky;  // supernodal_cholesky.h: CHOLMOD, kept out of this header

class SymmetricSystem {
 public:
  // kSparse: Eigen's simplicial LDLT (AMD), fastest for the spring models' small, sparse
  // systems; kSupernodal: CHOLMOD's supernodal Cholesky (BLAS kernels), for large FEM systems.
  enum class Backend { kBanded, kSparse, kSupernodal };

  struct Factorization {
    bool positive_definite = false;  // every scaled pivot > small_pivot_tolerance
    // With count_pivots, when not positive definite: the number of eigenvalues of S A S +
    // shift I at or below small_pivot_tolerance (CountEigenvaluesBelow). For a positive
    // semi-definite A with a clean gap this is the dimension of its null space: the number
    // of mechanism modes. Otherwise the number of scaled pivots at or below the tolerance.
    int small_pivots = 0;
    double min_pivot = 0.0;  // smallest scaled pivot
  };

  SymmetricSystem();
  ~SymmetricSystem();
  // `lower` lists the (row, col), row >= col, of every entry that may become nonzero; the
  // diagonal is added automatically. Duplicates are allowed.
  SymmetricSystem(int n, std::vector<std::pair<int, int>> lower, Backend backend);

  int size() const { return n_; }
  Backend backend() const { return backend_; }
  // The slot of entry (row, col); requires row >= col and the entry in the pattern.
  int Slot(int row, int col) const;
  double* values() { return values_; }
  void SetZero();
  // The assembled (unscaled) matrix, both triangles, as a dense matrix. For tests.
  Matrix ToDense() const;

  // Factorises S A S + shift I. With `count_pivots` false the factorisation may stop at the
  // first non-positive pivot (positive_definite false, small_pivots meaningless), which is all
  // a Newton step needs; with it true every pivot is examined, by the shared counter when the
  // backend's own factorisation is not positive definite.
  Factorization Factorize(double shift, double small_pivot_tolerance, bool count_pivots);
  // The number of eigenvalues of S A S + shift I below `tolerance`, exactly (Sylvester's law
  // of inertia on one more LDLT), with the matrix as assembled. Leaves no factorisation for
  // Solve().
  int CountEigenvaluesBelow(double shift, double tolerance);
  // Factorises S A S + shift I for Solve() with a simplicial LDLT whatever the backend, when A
  // may be indefinite (an unstable equilibrium's tangent): Factorize() keeps no factorisation
  // of an indefinite matrix. min_pivot is 0 when an exactly zero pivot stopped it (a singular
  // matrix; Solve() must not follow).
  Factorization FactorizeIndefinite(double shift);
  // Overwrites b with the solution of (A + shift S^-2) x = b, using the last Factorize().
  void Solve(Vector& b) const;
  // The bytes this system holds, its factor included at the size its analysis gives (a
  // factorisation allocates no more), for memory estimates.
  double Bytes() const;

 private:
  void ComputeScaling();
  // The sparse backends' symbolic analysis of sparse_work_'s pattern.
  void AnalyseSparse();
  // The position of (row, col) in the compressed lower triangle.
  int SparseSlot(int row, int col) const;
  // sparse_work_ = S A S + shift I, from whichever storage the backend assembles into.
  void ScaleIntoWork(double shift);
  // The shared pivot count: a simplicial LDLT of sparse_work_ (filled first unless `scaled`),
  // which Solve() then uses.
  Factorization CountPivots(double shift, double tolerance, bool scaled);
  // The lower triangle of a matrix in band storage, as a dense matrix (upper triangle zero).
  Matrix BandToDense(const Matrix& band) const;

  int n_ = 0;
  Backend backend_ = Backend::kBanded;
  double* values_ = nullptr;  // points into band_ or sparse_ storage
  Vector scale_;              // S

  // Banded backend, LAPACK's lower band storage: A(r, c) is band_(r - c, c), r - c <= bandwidth_.
  int bandwidth_ = 0;
  Matrix band_;
  // The Cholesky factor L of S A S + shift I, in the same storage.
  Matrix band_factor_;

  // Sparse backends: lower triangle in compressed column storage (the banded backend keeps the
  // pattern, with zero values, for the pivot count).
  Eigen::SparseMatrix<double> sparse_;
  Eigen::SparseMatrix<double> sparse_work_;
  std::vector<int> diagonal_slot_;
  // Eigen's simplicial LDLT, with the size of its factor (allocated by the analysis) readable.
  struct SparseLdlt
      : Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::AMDOrdering<int>> {
    Eigen::Index FactorEntries() const { return m_matrix.nonZeros(); }
  };
  // Eigen's sparse solvers cannot be copied: a copy of the system analyses the pattern anew
  // (once per thread, not once per solve). A copy carries the matrix and the pattern but no
  // numeric factorisation (copying an unfactorised Eigen LDLT reads its uninitialised status,
  // which UBSan flags); a move may carry it or not. Factorize() before Solve(), as every
  // caller does.
  std::unique_ptr<SparseLdlt> sldlt_;
  // Supernodal backend: CHOLMOD on the same compressed lower triangle (sparse_work_).
  std::unique_ptr<SupernodalCholesky> supernodal_;
  bool used_sldlt_ = false;  // the last factorisation is sldlt_'s (the sparse backend, a count)

 public:
  SymmetricSystem(const SymmetricSystem& other);
  SymmetricSystem& operator=(const SymmetricSystem& other);
  SymmetricSystem(SymmetricSystem&& other) noexcept;
  SymmetricSystem& operator=(SymmetricSystem&& other) noexcept;

 private:
  // values_ points into storage owned by this object: re-aim it after a copy or move.
  void RebindValues() {
    values_ = backend_ == Backend::kBanded ? band_.data() : sparse_.valuePtr();
  }
};

}  // namespace springfit
