// Refines spring weights (stiffness; 0 = absent) by minimising the displacement cost itself,
//   f(w) = sum_k sum_i |X^R_ik - X^M_ik(w)|^2,   w >= 0,
// the maximum-likelihood fit for Gaussian noise on measured positions. The force-balance
// NNLS (engine/linalg/nnls.h) puts that noise into its matrix and so shrinks every weight (at 1%
// noise on paper-iso-5x5 the weights come out near 0.6 instead of 1); this fit does not.
//
// Bounded Gauss-Newton with Levenberg-Marquardt damping: the equilibrium's sensitivity to
// w_j is du/dw_j = H^-1 g_j, H the tangent stiffness at the model's equilibrium and g_j the
// force spring j exerts per unit stiffness (one factorisation per load case, then one solve
// per gene); each step is the non-negative least-squares problem
//   min |J w' - (J w - r)|^2 + lambda |D (w' - w)|^2,  w' >= 0,   D^2 = diag(J^T J),
// solved by SolveDenseNnls, and accepted when f decreases. A weight that reaches 0 has left the
// model; one whose gradient points back in returns.
#pragma once
#include <string>
#include <vector>

#include "engine/api/problem.h"
#include "engine/problem/cost.h"
#include "engine/runtime/interruption.h"

namespace springfit {

struct RefinementOptions {
  int max_iterations = 30;            // accepted steps
  double relative_tolerance = 1e-10;  // stop when f falls by less than this fraction
  double initial_damping = 1e-4;      // lambda at the start, relative to D^2
  // Levenberg-Marquardt's damping: divided by damping_decrease after a step that lowers the
  // cost (never below min_damping), multiplied by damping_increase after one that does not,
  // at most max_damping_attempts times per step; none lowering it ends the refinement at a
  // (local) minimum.
  double damping_decrease = 3.0;
  double damping_increase = 10.0;
  double min_damping = 1e-12;
  int max_damping_attempts = 12;
  // Dense Jacobians (rows x genes, one solve per gene and load case) and a dense bounded
  // least-squares step per attempt, cubic in the genes: larger scenes keep the force-balance
  // weights.
  int max_genes = 1000;

  // Throws std::invalid_argument naming the field, its value and the rule it breaks.
  void Validate(const std::string& owner = "RefinementOptions") const;
};

struct RefinementResult {
  bool refined = false;         // false: not run (too many genes, or the start has no equilibrium)
  std::vector<double> weights;  // per gene
  Evaluation evaluation;        // of the refined model
  double initial_cost = 0.0;
  int iterations = 0;      // accepted steps
  bool converged = false;  // stopped by the tolerance rather than the iteration limit
  // Per gene: the weight's standard error at the optimum, s^2 [(J^T J)^-1]_jj with
  // s^2 = f / (rows - positive weights); empty when J^T J is singular (then the caller falls
  // back to the force balance's standard errors).
  std::vector<double> sigma;
};

// `usable[g]` false holds gene g at 0 (an unseen spring).
// Throws Interrupted when `interruption` stops it.
RefinementResult RefineWeights(const Problem& problem, const std::vector<double>& start,
                               const std::vector<bool>& usable,
                               const RefinementOptions& options = {},
                               Interruption* interruption = nullptr);

}  // namespace springfit
