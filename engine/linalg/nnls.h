// Non-negative least squares on a sparse matrix: min |A x - b|  subject to  x >= 0.
//
// Eigen 3.4 (Debian 12) has no NNLS and a dense one would not hold the 40,000 columns of a
// 100x100 grid, so this is the block principal pivoting method of Kim and Park (SIAM J. Sci.
// Comput. 33(6), 2011): guess the set F of positive variables, solve the unconstrained
// problem on F, and exchange every variable that breaks the optimality conditions at once;
// when exchanges stop reducing the number of violations, Murty's rule (exchange only the
// violating variable of largest index) guarantees termination. Identifying a spring network
// from exact data needs one solve: the true weights are positive where springs are, and the
// optimality conditions hold at once.
//
// Each solve on F uses the normal equations of the column-scaled matrix with a sparse LDLT
// (Eigen's SimplicialLDLT, AMD ordering), then iterative refinement on the residual, which
// recovers the accuracy the normal equations' squared condition number costs.
#pragma once
#include <string>
#include <vector>

#include "engine/linalg/linalg.h"
#include "engine/linalg/nnls_result.h"
#include "engine/runtime/interruption.h"

namespace springfit {

struct NnlsOptions {
  // Pivoting rounds before giving up (the last iterate is returned, clipped at 0, with
  // converged false). 0 = min(10 + 3n, 100). Exact data needs 1 round and noisy data a few;
  // a problem that takes more is nearly degenerate (nearly collinear nodes: 2,000 columns
  // cycled past 6,000 rounds, a minute and more, without converging), where more rounds do
  // not help and Murty's single exchanges would take as many rounds as columns.
  int max_iterations = 0;
  // A variable counts as negative below -tolerance * max|x|, a gradient component as
  // negative below -tolerance * |A^T b|_inf (both on unit-norm columns): relative, so that
  // units do not matter.
  double tolerance = 1e-10;
  // Refinement steps after each normal-equations solve.
  int refinement_steps = 2;
  // Rounds of exchanging whole violating sets before falling back to single exchanges.
  int full_exchange_budget = 3;

  // Throws std::invalid_argument naming the field, its value and the rule it breaks; `owner`
  // names the struct holding these options, if any.
  void Validate(const std::string& owner = "NnlsOptions") const;
};

// Columns with `usable[j]` false are held at 0 (e.g. zero columns).
// Throws Interrupted when `interruption` stops it (checked once per pivoting round).
NnlsResult SolveNnls(const SparseMatrix& a, const Vector& b, const std::vector<bool>& usable,
                     const NnlsOptions& options = {}, Interruption* interruption = nullptr);
// The same for a dense matrix (the Levenberg-Marquardt steps of stiffness_refinement.h, whose
// Jacobians are dense): its normal matrix is formed once, with dense products, and each
// round factorises the free set's block of it by a dense LDLT.
NnlsResult SolveDenseNnls(const Matrix& a, const Vector& b, const std::vector<bool>& usable,
                          const NnlsOptions& options = {});

}  // namespace springfit
