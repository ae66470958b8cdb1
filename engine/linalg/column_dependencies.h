// The linear dependencies among a sparse matrix's columns, at any size: which columns a basis
// leaves out, and each one's fundamental circuit (the basis columns it is a combination of).
//
// How: SuiteSparseQR's rank-revealing sparse QR (Heath's method: a column whose remaining norm
// falls to the tolerance is dependent), on columns of unit norm so that the tolerance is
// unit-free. Heath's rank can come out too high (a dependent column keeps a residual above
// the tolerance: fem-kidney-2d-fine's force balance has 12 dependencies, Heath finds 10), so
// the basis is confirmed: the smallest singular value of its factor R11 is estimated by
// inverse iteration with R11's triangular solves; while it is within a margin of the
// tolerance, the basis column its singular vector weighs most becomes dependent and the rest
// is factored again. Each circuit is then a least-squares solve on the basis with R11 (the
// corrected semi-normal equations), its cost bounded before it starts.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "engine/linalg/linalg.h"
#include "engine/runtime/interruption.h"

namespace springfit {

struct ColumnDependencyOptions {
  // The QR's fill-reducing column ordering. METIS on A^T A: on the Gmsh blocks' force balance it
  // about halves R11's fill and the QR's time against COLAMD (bench/RESULTS.md, "Identifiability
  // at scale"). The ordering chooses the basis, not the groups.
  enum class Ordering { kMetis, kColamd };
  Ordering ordering = Ordering::kMetis;
  // A column is dependent when its residual after the columns before it falls to this
  // (columns of unit norm). Unit-free.
  double rank_tolerance = 1e-9;
  // A circuit's coefficient below this, relative to its largest (and 1), is not part of it.
  double circuit_tolerance = 1e-8;
  // The rank is confirmed when the estimated smallest singular value of R11 is at least
  // this many times rank_tolerance: no combination of the basis columns is within the
  // tolerance of zero, the same rule that made the other columns dependent. A larger margin
  // also repairs bases that are ill-conditioned but independent (fem-kidney-2d-fine's METIS
  // basis has 5.3e-9 against singular values of A that jump from 2e-15 to 3.7e-5), which
  // would count dependencies that are not there.
  double confirm_margin = 1.0;
  // Inverse iterations for that estimate: each costs two triangular solves with R11. A missed
  // dependency stands out by orders of magnitude within one or two; fem-block-3d's estimate
  // after 10 is its smallest singular value to three digits (0.02095, SciPy's eigsh).
  int confirm_iterations = 10;
  // Refactorisations without one dependent column before giving up: each costs one more QR
  // (seconds on the large meshes) that cannot be interrupted. fem-kidney-2d-fine under COLAMD needs
  // 2, under METIS none.
  int max_repairs = 5;
  // The circuits cost about 2 (nonzeros(R11) + nonzeros(A's basis columns)) per dependent
  // column; beyond this product (seconds of one core) they are not traced.
  double max_trace_work = 2e10;

  // Throws std::invalid_argument naming the field (of `owner`), its value and the rule it
  // breaks.
  void Validate(const std::string& owner = "ColumnDependencyOptions") const;
};

struct ColumnDependencies {
  // False when the rank could not be confirmed or the circuits would cost more than allowed:
  // then no circuit is claimed, and `not_analysed` says why, for people.
  bool analysed = false;
  std::string not_analysed;
  int rank = 0;
  struct Circuit {
    int column = -1;                            // a dependent column (coefficient 1 in its circuit)
    std::vector<std::pair<int, double>> basis;  // (basis column, coefficient), by column
  };
  // One per dependent column, in order of the column.
  std::vector<Circuit> circuits;
};

// `a`'s columns must have unit norm (zero columns are dependent on anything: leave them out).
// Throws Interrupted when `interruption` stops it: checked after each QR (one QR call itself
// cannot be stopped) and between circuits.
ColumnDependencies FindColumnDependencies(const SparseMatrix& a,
                                          const ColumnDependencyOptions& options = {},
                                          Interruption* interruption = nullptr);

}  // namespace springfit
