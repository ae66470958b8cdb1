#include "engine/linalg/singular_values.h"

#include <algorithm>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

// LAPACK (Fortran; the trailing argument is the hidden length of the character argument).
extern "C" {
void dgesdd_(const char* jobz, const int* m, const int* n, double* a, const int* lda, double* s,
             double* u, const int* ldu, double* vt, const int* ldvt, double* work, const int* lwork,
             int* iwork, int* info, std::size_t jobz_len);
}

namespace springfit {

Vector SingularValues(const Matrix& a) {
  const int m = static_cast<int>(a.rows());
  const int n = static_cast<int>(a.cols());
  const int k = std::min(m, n);
  if (k == 0) return Vector();
  Matrix work_copy = a;  // dgesdd overwrites its input (column-major, as Eigen's default)
  Vector s(k);
  double unused = 0.0;  // u and vt: not referenced with jobz 'N'
  const int one = 1;
  const int lda = std::max(1, m);
  std::vector<int> iwork(static_cast<std::size_t>(8 * k));
  int info = 0;
  // The workspace LAPACK asks for, then the factorisation.
  double query = 0.0;
  int lwork = -1;
  dgesdd_("N", &m, &n, work_copy.data(), &lda, s.data(), &unused, &one, &unused, &one, &query,
          &lwork, iwork.data(), &info, 1);
  if (info == 0) {
    lwork = std::max(1, static_cast<int>(query));
    std::vector<double> work(static_cast<std::size_t>(lwork));
    dgesdd_("N", &m, &n, work_copy.data(), &lda, s.data(), &unused, &one, &unused, &one,
            work.data(), &lwork, iwork.data(), &info, 1);
  }
  if (info != 0) {
    throw std::runtime_error("singular values of a " + std::to_string(m) + "x" + std::to_string(n) +
                             " matrix: LAPACK dgesdd info " + std::to_string(info));
  }
  return s;  // (descending, as dgesdd returns them)
}

}  // namespace springfit
