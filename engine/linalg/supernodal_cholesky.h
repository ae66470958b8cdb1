// A supernodal sparse Cholesky factorisation (CHOLMOD, SuiteSparse) of a symmetric matrix given
// by its lower triangle in compressed columns: the pattern is analysed once (fill-reducing
// ordering: CHOLMOD's choice among AMD and METIS, elimination tree, supernodes) and every
// factorisation of new values on that pattern reuses it. The dense kernels of the supernodes
// run in BLAS, so large 3D systems factorise many times faster than with a simplicial
// factorisation (bench/RESULTS.md, "FEM references").
//
// Not thread-safe and not copyable; one per thread. It keeps no pointer to the caller's arrays.
#pragma once

#include <memory>

#include "engine/linalg/linalg.h"

namespace springfit {

class SupernodalCholesky {
 public:
  // `outer` (n + 1 column starts) and `inner` (row indices, ascending in each column) describe
  // the lower triangle, diagonal included.
  SupernodalCholesky(int n, const int* outer, const int* inner);
  ~SupernodalCholesky();
  SupernodalCholesky(const SupernodalCholesky&) = delete;
  SupernodalCholesky& operator=(const SupernodalCholesky&) = delete;

  // Factorises the matrix with these values, on the pattern given at construction (the same
  // arrays or a copy). Returns false when it is not positive definite (some pivot <= 0); the
  // factor is then unusable.
  bool Factorize(const int* outer, const int* inner, const double* values);
  // The pivots of the last successful factorisation: L_jj^2 in the factor's (permuted) order.
  Vector Pivots() const;
  // Overwrites b with A^-1 b, using the last successful factorisation.
  void Solve(Vector& b) const;
  // The same for every column of B at once (the supernodes' blocks then work on all columns).
  void Solve(Matrix& b) const;
  // The same as Solve(Matrix&), by one pass over the factor for all columns in springfit's own
  // loops (blocked_triangular_solve.h) instead of CHOLMOD's solve: twice as fast with the
  // reference BLAS, and the same bits whatever BLAS is installed.
  void SolveColumns(Matrix& b) const;
  // The bytes the factor holds once factorised (its supernodes' values and indices, known from
  // the analysis), for memory estimates.
  double FactorBytes() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace springfit
