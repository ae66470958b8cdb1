// Static equilibrium of a mass-spring model under one load case (or, with
// EquilibriumOptions::response kLinear, its linearised response at rest).
//
// The equilibrium minimises the potential energy over the free nodes' displacements u:
//   E(u) = sum_springs 1/2 k (L - l)^2 - sum_free F . u
// (docs/ARCHITECTURE.md, "Equilibria and numerics"). Newton's method with a backtracking (Armijo)
// line search on E: each step uses the exact spring Hessian when it is positive definite (quadratic
// convergence) and the projected one (compressive lateral term clamped at 0, see springs.h)
// when it is not. Constrained nodes (fixed or with a prescribed displacement) are not unknowns.
//
// A mechanism (a topology whose stiffness at rest is singular on the free nodes: a node with
// too few springs, an island cut off from every constrained node, a square without a diagonal)
// cannot carry a general load; RestMechanismModes() detects it before any Newton step, from the
// eigenvalues of the Jacobi-scaled rest stiffness with unit stiffness (see symmetric_system.h),
// and counts its modes.
//
// An EquilibriumSolver is built once per spring geometry and set of constrained nodes: that
// fixes the sparsity pattern, whose symbolic analysis is done in the constructor and reused by
// every solve. Not thread-safe; copy one per thread (a copy of a sparse-backed solver redoes
// the symbolic analysis once, see symmetric_system.h).
#pragma once

#include <string>
#include <vector>

#include "engine/api/model.h"
#include "engine/linalg/linalg.h"
#include "engine/linalg/symmetric_system.h"
#include "engine/model/springs.h"
#include "engine/runtime/interruption.h"

namespace springfit {

struct EnergyPoint;  // newton_iteration.h

// The rest stiffness's verdict (EquilibriumOptions::near_mechanism_tolerance): `modes`
// mechanism modes, and `near_modes` more directions along which the model is rigid but its
// relative stiffness is below near_mechanism_tolerance, where a solve in double precision is
// at the edge of what it resolves.
struct RestStability {
  int modes = 0;
  int near_modes = 0;
};

// Spring stiffness ratios from about this on are at the limit of double precision: the
// softest springs' contribution to a stiffness entry is below the stiffest's round-off.
inline constexpr double kStiffnessRatioLimit = 1e12;

// Why a solve did not converge, for messages: the reason, the iterations, the relative
// residual and the tolerance, e.g. "the Newton iteration limit was reached after 100
// iterations, with a force imbalance 32 times what its node allows (relative force residual
// 3.2e-09)".
std::string NotConvergedText(const EquilibriumSummary& summary);
// What double precision cannot decide about a model that did not converge: its near-mechanism
// modes, a stiffness ratio at or beyond kStiffnessRatioLimit. "" when neither; otherwise
// begins with "; ".
std::string PrecisionLimitText(const RestStability& stability, const ActiveSprings& springs);

class EquilibriumSolver {
 public:
  EquilibriumSolver() = default;
  // Keeps a pointer to `geometry`, which must outlive the solver.
  EquilibriumSolver(const SpringGeometry& geometry, FreeNodes free_nodes,
                    EquilibriumOptions options = {});

  const FreeNodes& free_nodes() const { return free_; }
  // Checked between Newton iterations (nullptr: never stopped); must outlive its use.
  void set_interruption(Interruption* interruption) { interruption_ = interruption; }
  const EquilibriumOptions& options() const { return options_; }

  // The number of mechanism modes of `springs` at rest with this solver's constrained nodes:
  // 0 for a model that carries any load. Depends on which springs are active, not on their
  // stiffness (see near_mechanism_tolerance): one factorisation, and a QR when the model is a
  // mechanism or near one.
  int RestMechanismModes(const ActiveSprings& springs) { return RestStabilityOf(springs).modes; }
  RestStability RestStabilityOf(const ActiveSprings& springs);

  // Solves for the equilibrium. `force` and `prescribed` are flat d*n vectors (entries of
  // free nodes in `prescribed` and of constrained nodes in `force` are ignored). `u` holds the
  // starting displacements of the free nodes on entry (the warm start; zero = from rest) and
  // the equilibrium on return; its constrained entries are set to `prescribed`.
  // Precondition: RestMechanismModes(springs) == 0 (otherwise the result is kNotConverged or
  // a meaningless equilibrium, never NaN). Never throws.
  EquilibriumSummary Solve(const ActiveSprings& springs, const Vector& force,
                           const Vector& prescribed, Vector& u);
  // Solve() whose first step may solve with `start_tangent`'s last factorisation as its chord
  // (EquilibriumOptions::chord_contraction): a solver of the same geometry and free nodes that
  // HoldsTangent() near `u` (the previous load step's, FactorizeTangent() at its equilibrium;
  // this solver itself after a Solve() of the same springs). nullptr: the first step
  // factorises. `start_tangent` must not change while this runs.
  EquilibriumSummary Solve(const ActiveSprings& springs, const Vector& force,
                           const Vector& prescribed, Vector& u,
                           const EquilibriumSolver* start_tangent);
  // Whether the last factorisation is a positive-definite tangent (exact, projected or
  // regularised) of the springs last solved or factorised, which Solve() may start from.
  bool HoldsTangent() const { return holds_tangent_; }
  // The bytes this solver holds once it has solved (its system and factor, its slots and its
  // work vectors), for memory estimates: known at construction.
  double Bytes() const;

  // Solves H x = b for every column b of `rhs` (free degrees of freedom, free-node order), H
  // the exact Hessian of E at `u` (an equilibrium from Solve): one factorisation, then one
  // solve per column. The sensitivity of an equilibrium to the stiffness is such a solve.
  // Returns false, leaving `rhs` unspecified, when H is not positive definite there.
  bool SolveWithTangent(const ActiveSprings& springs, const Vector& force, const Vector& u,
                        Matrix& rhs);
  // The same in two parts, for callers that solve with H many times (sensitivities applied as
  // operators): FactorizeTangent() factorises H at `u` and returns whether it is positive
  // definite; SolveTangent() overwrites b (free degrees of freedom) with H^-1 b, using the
  // last FactorizeTangent() as long as no other method of this solver has been called since.
  bool FactorizeTangent(const ActiveSprings& springs, const Vector& u);
  // At rest (u = 0) the tangent is the linear response's stiffness.
  // EnergyAndGradient() without the Hessian does not touch the factorisation. SolveTangent() and
  // EnergyAndGradient() without the Hessian only read the solver: several threads may call
  // them at once (the sparse and banded backends' solves are const), as long as no other
  // method runs meanwhile.
  void SolveTangent(Vector& b) const { system_.Solve(b); }

  // How far round-off leaves the displacements of an equilibrium `u` of the last Solve()
  // undetermined: |H^-1 r| (2-norm over the free nodes, in length units), r the force
  // imbalance each free node is allowed (its tolerance, signs from a fixed pattern), H the
  // exact tangent at u. Well-conditioned models give about the tolerance times the
  // displacement; a tangent that is nearly singular (a stiffness spread near 1e12, nearly
  // collinear springs) amplifies it, and normalised errors below this over |u| are noise.
  // `stable` is false when H is not positive definite: u is a saddle of the energy, not a
  // minimum (a straight column compressed past its buckling load stays straight by symmetry);
  // H^-1 r is then solved with an indefinite factorisation. spread is +inf when H is singular
  // (stable is then true: a singular tangent says nothing of stability).
  // One or two factorisations.
  struct Resolution {
    double spread = 0.0;
    bool stable = true;
  };
  Resolution DisplacementResolution(const ActiveSprings& springs, const Vector& u);

  // E(u) and its gradient on the free degrees of freedom (flat, free-node order). Exposed for
  // tests; `hessian` true also assembles the Hessian into the system (`projected` clamps it).
  double EnergyAndGradient(const ActiveSprings& springs, const Vector& force, const Vector& u,
                           Vector* gradient, bool hessian, bool projected);
  // The assembled Hessian as a dense matrix on the free degrees of freedom (tests only).
  Matrix AssembledHessian() const;

 private:
  template <int D>
  double Assemble(const ActiveSprings& springs, const Vector& force, const Vector& u,
                  Vector* gradient, bool hessian, bool projected, double* magnitude);
  template <int D>
  EquilibriumSummary SolveImpl(const ActiveSprings& springs, const Vector& force,
                               const Vector& prescribed, Vector& u,
                               const EquilibriumSolver* start_tangent);
  // SolveImpl's steps.
  // The load's force scale, which the relative tolerance multiplies.
  template <int D>
  double ForceScale(const ActiveSprings& springs, const Vector& force,
                    const Vector& prescribed) const;
  // Each free node's round-off force floor into floor_; returns the largest.
  double SetRoundoffFloors(const ActiveSprings& springs);
  // The largest imbalance of a free node over its tolerance (converged at <= 1).
  template <int D>
  double Excess(const Vector& gradient) const;
  // The stop tests before a step (converged, the iteration limit, an interruption), setting
  // the termination: nullptr to go on, else why it stopped ("" when it needs no words).
  const char* StopBeforeStep(EquilibriumSummary& summary);
  // The Newton step into step_ and its slope along the gradient: nullptr, or why there is none.
  template <int D>
  const char* NewtonStep(const ActiveSprings& springs, const Vector& force, const Vector& u,
                         EquilibriumSummary& summary, double& slope);
  // Shortens step_ where it would move a spring's ends by more than max_step of its length,
  // and sets its slope along the gradient: nullptr, or why it is no descent direction.
  template <int D>
  const char* LimitStep(const ActiveSprings& springs, double& slope);
  // Newton's steps (newton_iteration.h), on this solver's state.
  template <int D>
  struct NewtonSteps;
  // The point at step length alpha along step_ from u, into trial_u_ and trial_gradient_ (the
  // line search's trial, newton_iteration.h).
  template <int D>
  EnergyPoint TrialPoint(const ActiveSprings& springs, const Vector& force, const Vector& u,
                         double alpha);

  const SpringGeometry* geometry_ = nullptr;
  FreeNodes free_;
  EquilibriumOptions options_;
  int dim_ = 2;
  // slots_[spring * 3 * D*D + block * D*D + a*D + b]: the system slot receiving entry (a, b) of
  // block 0 = (i,i), 1 = (j,j), 2 = (i,j) of that spring, or -1 (constrained node, or the
  // upper triangle of a diagonal block).
  std::vector<int> slots_;
  SymmetricSystem system_;
  Interruption* interruption_ = nullptr;
  ActiveSprings unit_;  // the springs of a rest verdict, stiffness 1
  // Assembles the unit-stiffness rest matrix of `springs` into the system.
  void AssembleUnitRest(const ActiveSprings& springs);
  Vector gradient_, trial_gradient_, step_, trial_u_;
  std::vector<double> floor_;  // per free node: its round-off force floor (SolveImpl)
  double relative_ = 0.0;      // the relative force tolerance in force units (SolveImpl)
  // Chord steps (EquilibriumOptions::chord_contraction): the solver whose factorisation they
  // solve with (this one, a start tangent, or none), the last step's contraction of the
  // largest imbalance, and whether the last step was a chord step.
  const EquilibriumSolver* chord_ = nullptr;
  double contraction_ = 0.0;
  bool chord_step_ = false;
  bool holds_tangent_ = false;
};

}  // namespace springfit
