// Static equilibrium of a finite-element reference under one load case.
//
// The equilibrium minimises the potential energy over the free nodes' displacements u:
//   E(u) = sum_elements V0 W(F(u)) - lambda f . u,   constrained nodes at lambda * prescribed,
// at load fraction lambda = 1. Newton's method with an Armijo line search on E, the iteration
// the springs' solver runs too (newton_iteration.h): the exact tangent stiffness
// (fem_model.h), factorised on the scene's sparsity pattern (symbolic analysis once per
// solver); where it is not positive definite (a compressed nonlinear state), the
// Jacobi-scaled matrix is shifted until it is, so each step still descends. A configuration with an
// inverted element (J <= 0) has infinite energy for the neo-Hookean law, so the line search never
// enters one.
//
// Load stepping (continuation): the full load is tried from rest first (a linear material
// converges in one step); when Newton fails, the load increment is halved and the solve
// restarts from the last converged load level, and after each success the increment grows
// back. When the increment falls below 2^-max_load_cuts of the load, the reference has no
// equilibrium the solver can reach (an instability such as buckling under compression, or a
// load beyond what the material carries): the summary says so with the fraction reached.
//
// Not thread-safe; one per thread.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "engine/fem/fem_model.h"
#include "engine/linalg/symmetric_system.h"
#include "engine/model/equilibrium.h"

namespace springfit::fem {

struct FemSolverOptions {
  // Converged when the largest free-node force imbalance is at most
  //   max(relative_force_tolerance * force_scale, roundoff_force_tolerance * K_max * extent),
  // force_scale = max(largest external force, K_max * largest prescribed displacement), K_max
  // the largest diagonal entry of the rest stiffness and extent the diagonal of the nodes'
  // bounding box. Both unit-free, in (0, 1).
  double relative_force_tolerance = 1e-10;
  double roundoff_force_tolerance = 1e-13;
  int max_iterations = 50;         // Newton iterations per load increment, >= 1
  int max_line_search_steps = 40;  // step halvings before a Newton iteration gives up, >= 1
  double armijo = 1e-4;            // sufficient decrease c1, in (0, 1/2)
  int max_load_cuts = 12;          // smallest increment 2^-max_load_cuts of the load, in [0, 40]
  int max_load_steps = 500;        // increments tried in all (accepted or not), >= 1
  // A scaled pivot at or below this marks a free mode of the rest stiffness (a part of the
  // mesh not held by the constrained nodes), unit-free.
  double pivot_tolerance = 1e-10;
  // Systems of more free degrees of freedom than this are factorised by CHOLMOD's supernodal
  // Cholesky, smaller ones by Eigen's simplicial LDLT (bench/RESULTS.md, "FEM references": the
  // supernodal one wins from about this size on). >= 0.
  int supernodal_min_dofs = 2000;

  // Throws std::invalid_argument naming the field, its value and the rule.
  void Validate() const;
};

enum class FemTermination {
  kConverged,
  kNoEquilibrium,  // the load increment fell below its floor, or the step budget ran out
  kInverted,       // converged, but some element is inverted (J <= 0) at the equilibrium
  kFreeModes,      // the rest stiffness is singular on the free nodes; nothing was solved
};

struct FemSolveSummary {
  FemTermination termination = FemTermination::kNoEquilibrium;
  int iterations = 0;           // Newton iterations, all increments
  int load_steps = 0;           // accepted load increments (1 when the full load converged at once)
  int load_cuts = 0;            // increments that failed and were halved
  double reached = 0.0;         // load fraction of the last converged state
  double final_residual = 0.0;  // |gradient|_inf / force_scale at the end
  int inverted_element = -1;    // kInverted: the first inverted element
  int free_modes = 0;           // kFreeModes: the null-space dimension
  // One line on what happened (for kNoEquilibrium: the fraction reached and what to try).
  std::string message;

  bool converged() const { return termination == FemTermination::kConverged; }
};

class FemEquilibriumSolver {
 public:
  // Keeps a pointer to `model`, which must outlive the solver.
  FemEquilibriumSolver(const FemModel& model, FreeNodes free_nodes, FemSolverOptions options = {});

  const FreeNodes& free_nodes() const { return free_; }

  // Solves for the equilibrium under `force` (flat d*n; entries of constrained nodes ignored)
  // with constrained nodes at `prescribed` (flat d*n). `u` is set to the equilibrium (flat d*n,
  // constrained entries = prescribed). Throws nothing but Interrupted, when the solver's
  // interruption stops it between Newton iterations.
  FemSolveSummary Solve(const Vector& force, const Vector& prescribed, Vector& u);
  // Checked before every Newton iteration (a factorisation: the unit of work that bounds how
  // soon a stop takes effect). Null: never stopped.
  void set_interruption(Interruption* interruption) { interruption_ = interruption; }

  // E(u) at load fraction 1 and its gradient on the free degrees of freedom (free-node order);
  // `hessian` true also assembles the tangent. Infinite when an element is inadmissible.
  // Exposed for tests.
  double EnergyAndGradient(const Vector& force, const Vector& u, Vector* gradient, bool hessian);
  // The assembled tangent on the free degrees of freedom, dense (tests only).
  Matrix AssembledHessian() const { return system_.ToDense(); }

 private:
  template <int D>
  double Assemble(const Vector& force, double load, const Vector& u, Vector* gradient, bool hessian,
                  double* magnitude);
  double Energy(const Vector& force, double load, const Vector& u, Vector* gradient, bool hessian,
                double* magnitude);
  // Newton's steps at one load level (newton_iteration.h), on this solver's state.
  struct NewtonSteps;
  // Newton at one load level from u (in place); true when converged.
  bool Newton(const Vector& force, double load, double tolerance, Vector& u,
              FemSolveSummary& summary);
  // Assembles and factorises the rest stiffness: sets stiffness_scale_ and the factor, and
  // returns the number of free modes.
  int RestFreeModes();

  const FemModel* model_ = nullptr;
  FreeNodes free_;
  FemSolverOptions options_;
  int dim_ = 2;
  // Per element, (d+1)^2 blocks of d*d slots (row-major block (a, b), entry (i, k)): the
  // system slot of that entry of the lower triangle, or -1.
  std::vector<int> slots_;
  SymmetricSystem system_;
  Interruption* interruption_ = nullptr;
  double stiffness_scale_ = 0.0;  // K_max
  double extent_ = 0.0;
  // The system's factor is the rest stiffness's (from RestFreeModes).
  bool rest_factor_valid_ = false;
  std::optional<int> rest_modes_;  // RestFreeModes(), computed at the first Solve
  Vector gradient_, step_, trial_, trial_gradient_;
};

}  // namespace springfit::fem
