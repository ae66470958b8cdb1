// What a non-negative least-squares solve (engine/linalg/nnls.h) returns: apart from the solver,
// so that a result that reports it (strategy direct's) does not reach the solver.
#pragma once

#include "engine/linalg/linalg.h"

namespace springfit {

struct NnlsResult {
  Vector x;  // >= 0; 0 on columns not usable
  // The optimality conditions hold within the tolerance, and the least-squares solves on the
  // positive set were accurate (false for a singular set the ridge could not resolve).
  bool converged = false;
  int iterations = 0;  // pivoting rounds
  int factorizations = 0;
  double residual_norm = 0.0;  // |A x - b|
};

}  // namespace springfit
