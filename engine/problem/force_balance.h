// The equilibrium equations of the training model, written at the reference's equilibrium
// positions, as a linear system in the spring weights (docs/ARCHITECTURE.md, "The identification
// cost and the strategies"):
//
//   for load case k and free node i:   sum_j w_ij g_ij(X^R_k) = -F_ext,i,k
//   g_ij(X) = -(|X_i - X_j| - l_ij) (X_i - X_j) / |X_i - X_j|
//
// w_ij >= 0 is the stiffness of spring (i, j), 0 when absent. One row per coordinate of a
// free node per load case, one column per gene. For an MSS reference whose springs are all
// candidates, A w = b holds exactly at the reference's stiffness. Under the linear response
// (Problem::response()) g_ij is the linearised spring's: -(n0 . (u_i - u_j)) n0, n0 the rest
// direction.
#pragma once
#include <Eigen/SparseCore>
#include <optional>
#include <vector>

#include "engine/api/problem.h"

namespace springfit {

struct ForceBalance {
  SparseMatrix a;  // rows: (load case, free node, coordinate); columns: genes
  Vector b;        // -F_ext
  // Per gene: the largest length change of its spring over the load cases, relative to its
  // rest length. 0 = no load case stretches or compresses it: its weight is not seen.
  std::vector<double> strain;
  // The first row of each load case's block (its free coordinates in free-node order), and
  // one past the last block.
  std::vector<Eigen::Index> row_offset;
};

// At the reference's equilibria, or at the configurations rest + `displacements[k]` (a
// model's equilibria: then column g of case k's block is the force the gene's spring exerts
// per unit stiffness there, what the equilibrium's sensitivity to that stiffness needs).
ForceBalance AssembleForceBalance(const Problem& problem,
                                  const std::vector<Vector>* displacements = nullptr);

// The genes some load case sees: strained by at least `unseen_strain` (relative) in a case
// where one of its nodes is free, so that its column of A is not zero. The one rule for
// strategy direct and the identifiability report.
std::vector<bool> SeenGenes(const ForceBalance& fb, double unseen_strain);
// The default `unseen_strain`: a relative length change at round-off.
inline constexpr double kUnseenStrain = 1e-12;

}  // namespace springfit
