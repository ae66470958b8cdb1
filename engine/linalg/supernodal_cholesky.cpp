#include "engine/linalg/supernodal_cholesky.h"

#include "engine/linalg/blocked_triangular_solve.h"

#include <cholmod.h>

#include <dlfcn.h>

#include <cstring>
#include <mutex>
#include <stdexcept>
#include <vector>

namespace springfit {

namespace {

// The supernodes' dense kernels run in whatever BLAS libblas.so.3 is. The install script leaves
// Debian's reference BLAS, whose results are the same bits on every x86-64 machine (the
// examples and determinism across daemons rely on that; an optimised BLAS chooses its kernels by
// the processor). Where one has been installed all the same (OpenBLAS), its own threads are
// switched off: springfit's pool runs the factorisations in parallel, one per worker, and a
// result must not depend on the machine's cores. Looked up at run time, so any BLAS works.
void OneBlasThread() {
  static std::once_flag once;
  std::call_once(once, [] {
    using SetThreads = void (*)(int);
    if (auto set = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads")))
      set(1);
  });
}

}  // namespace

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
  OneBlasThread();
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

double SupernodalCholesky::FactorBytes() const {
  const cholmod_factor& l = *state_->factor;
  // (values; supernode row indices and pointers; the permutation and column counts)
  return 8.0 * static_cast<double>(l.xsize) + 4.0 * static_cast<double>(l.ssize) +
         4.0 * 4.0 * static_cast<double>(l.nsuper + 1) + 4.0 * 3.0 * static_cast<double>(l.n);
}

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

namespace {

// Overwrites the n x columns array `b` (column-major) with A^-1 b.
void SolveInPlace(cholmod_factor* factor, cholmod_common& common, int n, Eigen::Index columns,
                  double* b) {
  if (columns == 0) return;
  cholmod_dense rhs;
  std::memset(&rhs, 0, sizeof rhs);
  rhs.nrow = static_cast<std::size_t>(n);
  rhs.ncol = static_cast<std::size_t>(columns);
  rhs.nzmax = rhs.nrow * rhs.ncol;
  rhs.d = static_cast<std::size_t>(n);
  rhs.x = b;
  rhs.xtype = CHOLMOD_REAL;
  rhs.dtype = CHOLMOD_DOUBLE;
  cholmod_dense* x = cholmod_solve(CHOLMOD_A, factor, &rhs, &common);
  if (!x) throw std::runtime_error("CHOLMOD solve failed");
  std::memcpy(b, x->x, sizeof(double) * rhs.nzmax);
  cholmod_free_dense(&x, &common);
}

}  // namespace

void SupernodalCholesky::Solve(Vector& b) const {
  SolveInPlace(state_->factor, state_->common, state_->n, 1, b.data());
}

void SupernodalCholesky::Solve(Matrix& b) const {
  SolveInPlace(state_->factor, state_->common, state_->n, b.cols(), b.data());
}

void SupernodalCholesky::SolveColumns(Matrix& b) const {
  const cholmod_factor* f = state_->factor;
  const auto* super = static_cast<const int*>(f->super);
  const auto* pi = static_cast<const int*>(f->pi);
  const auto* px = static_cast<const int*>(f->px);
  const auto* rows = static_cast<const int*>(f->s);
  const auto* x = static_cast<const double*>(f->x);
  const auto* perm = static_cast<const int*>(f->Perm);
  // Per column, its supernode: the block's rows start with the supernode's own columns, so
  // column j's entries from its diagonal down are the block's rows from j's place on.
  std::vector<int> supernode_of(static_cast<std::size_t>(state_->n));
  for (std::size_t s = 0; s < f->nsuper; ++s)
    for (int j = super[s]; j < super[s + 1]; ++j)
      supernode_of[static_cast<std::size_t>(j)] = static_cast<int>(s);
  const auto column = [&](Eigen::Index j) {
    const int s = supernode_of[static_cast<std::size_t>(j)];
    const int local = static_cast<int>(j) - super[s];
    const int height = pi[s + 1] - pi[s];
    return FactorColumn{rows + pi[s] + local,
                        x + px[s] + static_cast<std::ptrdiff_t>(local) * height + local,
                        height - local};
  };
  // L L^T = P A P^T, row k of the permuted system being row perm[k] of A.
  RowBlock y(b.rows(), b.cols());
  const auto at = [perm](Eigen::Index k) { return perm ? perm[k] : k; };  // (null: natural)
  for (Eigen::Index k = 0; k < b.rows(); ++k) y.row(k) = b.row(at(k));
  SolveWithCholeskyFactor(state_->n, column, y);
  for (Eigen::Index k = 0; k < b.rows(); ++k) b.row(at(k)) = y.row(k);
}

}  // namespace springfit
