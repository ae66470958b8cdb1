#include "engine/supernodal_cholesky.h"

#include <cholmod.h>

#include <cstring>
#include <stdexcept>

namespace springfit {

struct SupernodalCholesky::State {
  int n = 0;
  cholmod_common common;
  cholmod_factor* factor = nullptr;
  cholmod_sparse view;  // the caller's arrays, wrapped; values set per factorisation

  State() { cholmod_start(&common); }
  ~State() {
    if (factor) cholmod_free_factor(&factor, &common);
    cholmod_finish(&common);
  }
};

SupernodalCholesky::SupernodalCholesky(int n, const int* outer, const int* inner)
    : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.n = n;
  s.common.print = 0;  // failures are reported by the return value, never on standard output
  s.common.supernodal = CHOLMOD_SUPERNODAL;
  s.common.final_ll = 1;
  std::memset(&s.view, 0, sizeof s.view);
  s.view.nrow = static_cast<std::size_t>(n);
  s.view.ncol = static_cast<std::size_t>(n);
  s.view.nzmax = static_cast<std::size_t>(outer[n]);
  s.view.p = const_cast<int*>(outer);
  s.view.i = const_cast<int*>(inner);
  s.view.stype = -1;  // the lower triangle holds the matrix
  s.view.itype = CHOLMOD_INT;
  s.view.xtype = CHOLMOD_PATTERN;
  s.view.dtype = CHOLMOD_DOUBLE;
  s.view.sorted = 1;
  s.view.packed = 1;
  s.factor = cholmod_analyze(&s.view, &s.common);
  if (!s.factor) throw std::runtime_error("CHOLMOD could not analyse the sparsity pattern");
  s.view.xtype = CHOLMOD_REAL;
}

SupernodalCholesky::~SupernodalCholesky() = default;

bool SupernodalCholesky::Factorize(const int* outer, const int* inner, const double* values) {
  State& s = *state_;
  s.view.p = const_cast<int*>(outer);
  s.view.i = const_cast<int*>(inner);
  s.view.x = const_cast<double*>(values);
  s.common.status = CHOLMOD_OK;
  cholmod_factorize(&s.view, s.factor, &s.common);
  return s.common.status == CHOLMOD_OK && s.factor->minor == s.factor->n;
}

Vector SupernodalCholesky::Pivots() const {
  const cholmod_factor* f = state_->factor;
  Vector pivots(state_->n);
  const auto* super = static_cast<const int*>(f->super);
  const auto* pi = static_cast<const int*>(f->pi);
  const auto* px = static_cast<const int*>(f->px);
  const auto* x = static_cast<const double*>(f->x);
  // Supernode s holds columns super[s] .. super[s+1]-1 as a dense block of pi[s+1]-pi[s] rows,
  // column-major from x[px[s]]; its leading square block is lower triangular.
  for (std::size_t s = 0; s < f->nsuper; ++s) {
    const int rows = pi[s + 1] - pi[s];
    for (int j = super[s]; j < super[s + 1]; ++j) {
      const int local = j - super[s];
      const double l = x[px[s] + static_cast<std::ptrdiff_t>(local) * rows + local];
      pivots[j] = l * l;
    }
  }
  return pivots;
}

void SupernodalCholesky::Solve(Vector& b) const {
  State& s = *state_;
  cholmod_dense rhs;
  std::memset(&rhs, 0, sizeof rhs);
  rhs.nrow = static_cast<std::size_t>(s.n);
  rhs.ncol = 1;
  rhs.nzmax = static_cast<std::size_t>(s.n);
  rhs.d = static_cast<std::size_t>(s.n);
  rhs.x = b.data();
  rhs.xtype = CHOLMOD_REAL;
  rhs.dtype = CHOLMOD_DOUBLE;
  cholmod_dense* x = cholmod_solve(CHOLMOD_A, s.factor, &rhs, &s.common);
  if (!x) throw std::runtime_error("CHOLMOD solve failed");
  std::memcpy(b.data(), x->x, sizeof(double) * static_cast<std::size_t>(s.n));
  cholmod_free_dense(&x, &s.common);
}

}  // namespace springfit
