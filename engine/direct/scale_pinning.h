// Load cases that only prescribe displacements put no external force on a free node: the
// force balance is homogeneous, A w = 0, and w = 0 solves it. The data then fix the weights
// up to one common factor (scaling every stiffness leaves every equilibrium where it was),
// so one weight is pinned to 1 and the others solved relative to it:
//   min |A' w' + a_p|,  w' >= 0,   A' = A without column p, a_p column p.
// The pin must be a spring that is present: a pinned absent spring cannot reach the null
// space. Column norms do not tell (absent candidates, often longer, strain the most: on
// kidney-2d the six largest columns are all absent springs). The null vector itself does:
// the direction A nearly annihilates, found by inverse iteration on the normal matrix of the
// unit-norm columns, has its largest component (on those columns) on a present spring. That
// spring is pinned.
#pragma once
#include <optional>
#include <vector>

#include "engine/linalg/nnls.h"
#include "engine/problem/force_balance.h"

namespace springfit {

struct PinOptions {
  int inverse_iterations = 6;  // the gap to the next singular value is wide for identifiable data
  double shift = 1e-12;        // added to the unit diagonal of the normal matrix, so it factorises
};

struct PinnedSolution {
  int pinned_gene = -1;
  NnlsResult nnls;            // x: the other weights, 0 at the pin
  Vector rhs;                 // -a_p: the right-hand side the NNLS solved
  std::vector<bool> columns;  // the usable columns but the pin
};

// nullopt when no column is usable, or the normal matrix does not factorise.
std::optional<PinnedSolution> SolvePinnedNnls(const SparseMatrix& a,
                                              const std::vector<bool>& usable,
                                              const PinOptions& pins = {},
                                              const NnlsOptions& nnls = {},
                                              Interruption* interruption = nullptr);

}  // namespace springfit
