// The engine's public surface (engine/api/): the vocabulary of a mass-spring model that the
// scene's preparation, the solvers and the results share. A topology (Genome), which nodes a
// load case frees, the springs of a model, and what an equilibrium solve was asked and did.
// The solvers themselves are internal (engine/model/equilibrium.h, springs.h).
#pragma once

#include <cstdint>
#include <vector>

#include "engine/api/scene.h"
#include "engine/linalg/linalg.h"

namespace springfit {

// A topology over a problem's genes: one bit per gene, 1 = the candidate spring is present
// (engine/api/problem.h lays the genes out).
using Genome = std::vector<std::uint8_t>;

// Which nodes are the unknowns of a load case: every solver (the MSS's, the FEM's), the
// rigidity test and the fits index their free degrees of freedom through it
// (engine/model/free_nodes.cpp).
// free_index[node] is the node's index among the free nodes, or -1 when the node is
// constrained.
struct FreeNodes {
  std::vector<int> free_index;
  int count = 0;

  // `constrained[node]` true for fixed nodes and nodes with a prescribed displacement.
  static FreeNodes FromConstrained(const std::vector<bool>& constrained);
  friend bool operator==(const FreeNodes&, const FreeNodes&) = default;
};

// A fixed set of potential springs over a scene's nodes (the candidates, or a reference's own
// springs): endpoints and rest lengths. Constant after construction.
struct SpringGeometry {
  int dimension = 2;
  std::vector<NodePair> pairs;
  std::vector<double> rest_length;
  Vector rest_separation;  // X_i - X_j at rest, flat d per spring

  SpringGeometry() = default;
  // Precondition: every pair is in range, first != second, rest positions distinct.
  SpringGeometry(int dimension, const Vector& rest, std::vector<NodePair> pairs);
  int size() const { return static_cast<int>(pairs.size()); }
  double MaxRestLength() const;
};

// The springs present in one model: indices into a SpringGeometry and their stiffness.
struct ActiveSprings {
  std::vector<int> index;
  std::vector<double> stiffness;  // > 0, parallel to index

  int size() const { return static_cast<int>(index.size()); }
  double MaxStiffness() const;
};

enum class Termination {
  kConverged,     // |gradient|_inf <= tolerance (see EquilibriumOptions)
  kNotConverged,  // iteration limit reached or the line search found no decrease
  kMechanism,     // the rest stiffness is singular on the free nodes; no solve was attempted
  kNotSolved,     // not attempted: another load case's mechanism already decided
                  // (engine/problem/cost.h)
  kInterrupted,   // stopped between iterations by the solver's Interruption
};

struct EquilibriumOptions {
  // kLinear: the springs' linearised response at rest (springs.h, SpringState::Linearised): the
  // energy is quadratic, Newton's first step solves it and a second, if any, removes round-off.
  // Set from the scene by Problem (search.response).
  Response response = Response::kNonlinear;
  // Converged when every free node's force imbalance is at most
  //   max(relative_force_tolerance * force_scale, roundoff_force_tolerance * max k l),
  // force_scale = max(largest external force, largest k * prescribed displacement over the
  // springs to a displaced node), the max over the node's springs. The second term is the
  // floor that round-off allows: a spring's force is computed from L - l, which carries an
  // error of about machine epsilon times l. Per node: the scene's stiffest spring does not set
  // a soft region's floor (it did, and tiny loads on soft springs "converged" unmoved). Both
  // are unit-free, in (0, 1).
  double relative_force_tolerance = 1e-10;
  double roundoff_force_tolerance = 1e-13;
  int max_iterations = 100;  // Newton iterations; the projected Hessian converges only linearly
  int max_line_search_steps = 50;  // halvings of the step before giving up
  double armijo = 1e-4;            // sufficient decrease parameter c1, in (0, 1/2)
  // Largest change of any spring's separation X_i - X_j in one Newton step, as a fraction of
  // its rest length (> 0). Moderate loads never reach it; large ones walk.
  double max_step = 0.5;
  // A Newton step trusts the exact Hessian only when every Jacobi-scaled pivot is above this
  // (unit-free). It sits a little above round-off, which is about 1e-16 times the number of
  // springs at a node: a stiffness ratio of 1e12 gives scaled pivots of about 1e-12, which a
  // step can still use, and where double precision cannot tell a pivot from zero the step
  // takes the projected, then regularised, Hessian.
  double pivot_tolerance = 1e-14;
  // The rest verdict (RestStabilityOf) depends on the geometry alone: the null space of
  // sum k n n^T is the rigidity matrix's whatever the (positive) stiffness, so it is decided on
  // the springs with stiffness 1 and a stiffness spread of 1e12 cannot make a model a
  // mechanism. First an LDLT of the Jacobi-scaled unit-stiffness rest matrix counts its
  // eigenvalues below near_mechanism_tolerance (0 for almost every model: no more work). Those
  // are mechanism modes or so close to them that the stiffness matrix cannot tell (a rigid
  // strip 300 cells long and one wide has 1e-10). Then a QR of the rigidity matrix
  // (engine/model/rigidity.h), which resolves twice the digits, counts as mechanism modes only its
  // singular values at or below rigidity_tolerance; an exact mechanism's are round-off, about
  // 1e-15. The rest are near-mechanism modes: rigid, but stiff along them only to about their
  // singular value squared, relative.
  double near_mechanism_tolerance = 1e-10;
  double rigidity_tolerance = 1e-12;
  // Free-node degrees of freedom up to which the banded factorisation is used; above it the
  // sparse one. On grids numbered row by row the banded one also wins up to 20x20, not on
  // irregular meshes in their mesher's numbering (bench/RESULTS.md, solve section).
  int banded_max_dofs = 96;
  // Free-node degrees of freedom above which CHOLMOD's supernodal Cholesky replaces Eigen's
  // simplicial LDLT, whose fill makes it an order of magnitude slower on large grids
  // (bench/RESULTS.md, "Control within a second": the 316 x 316 grid). Above every example's
  // size, so that their trajectories do not change.
  int supernodal_min_dofs = 20000;
  // Chord steps: a Newton step may solve with a tangent factorised earlier (one solve in place
  // of a factorisation) while the step before it shrank the largest force imbalance to at most
  // this fraction; a step after a weaker contraction, and a step after a chord step whose line
  // search failed, factorise the tangent at the current point. Near a known equilibrium (the
  // previous load step's, the previous model's) a chord step contracts by about the change of
  // the tangent, and a solve costs a fraction of a factorisation (docs/ARCHITECTURE.md, "The
  // nonlinear fit"). 0: every step factorises (exact Newton, the default, so that every other
  // solve keeps its trajectory). In [0, 1).
  double chord_contraction = 0.0;

  // Throws std::invalid_argument naming the field, its value and the rule it breaks.
  void Validate() const;
};

struct EquilibriumSummary {
  Termination termination = Termination::kNotConverged;
  int iterations = 0;             // Newton steps taken
  int projected_steps = 0;        // of which on the projected Hessian
  int chord_steps = 0;            // of which solved with an earlier factorisation
  int line_search_steps = 0;      // step halvings in all
  double initial_residual = 0.0;  // |gradient|_inf / force_scale at the start
  double final_residual = 0.0;    // |gradient|_inf / force_scale at the end
  int mechanism_modes = 0;        // kMechanism: the rest stiffness's null-space dimension
  // Set by the cost function (engine/problem/cost.h) from the rest verdict: directions along which
  // the model is rigid but too soft for double precision to be sure of (RestStability::near_modes).
  int near_mechanism_modes = 0;
  // The loosest free node's tolerance on its force imbalance, relative to force_scale (see
  // EquilibriumOptions::relative_force_tolerance): how far round-off lets the solve resolve
  // the load.
  double tolerance = 0.0;
  // The worst free node's force imbalance over its tolerance: <= 1 when converged.
  double excess = 0.0;
  // kNotConverged: why, in words ("the iteration limit (100) was reached", ...); static text.
  const char* why = "";

  bool converged() const { return termination == Termination::kConverged; }
};

}  // namespace springfit
