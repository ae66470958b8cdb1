// The singular values of a dense matrix, through LAPACK's divide-and-conquer SVD (dgesdd,
// values only): the dense check of a sparse QR's rank (model/rigidity.h). LAPACK is linked for
// the band Cholesky already; Eigen's BDCSVD computes the same values but is the costliest
// template the engine would instantiate (a minute and a half of one unit's compile time).
#pragma once

#include "engine/linalg/linalg.h"

namespace springfit {

// The min(rows, cols) singular values of `a`, descending; empty for an empty matrix. Throws
// std::runtime_error when LAPACK reports a failure (its iteration did not converge).
Vector SingularValues(const Matrix& a);

}  // namespace springfit
