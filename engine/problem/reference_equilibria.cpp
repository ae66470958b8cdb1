#include "engine/problem/reference_equilibria.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "engine/fem/fem_equilibrium.h"
#include "engine/runtime/input_error.h"
#include "engine/runtime/number_text.h"

namespace springfit {
namespace {

// A reference MSS's equilibrium must be determined to this fraction of its load at least: a
// load whose forces are closer to round-off than this does not tell topologies apart.
constexpr double kReferenceResolution = 1e-3;
// A reference equilibrium that round-off leaves uncertain by more than its own size
// (ReferenceSolve::resolution) is no data: the scene is refused.
constexpr double kReferenceUndetermined = 1.0;

// Newton iterations allowed to the reference MSS's equilibria. It is solved once per scene,
// from rest, where a hard load can take the projected Hessian's linear convergence for a
// hundred iterations and more (a 1 um line of nodes pulled to 65% stretch needs 138): it gets
// a larger, still bounded, budget.
constexpr int kReferenceMaxIterations = 1000;

// The reference's springs, each with its stiffness.
ActiveSprings ReferenceSprings(const Reference& ref) {
  ActiveSprings springs;
  for (std::size_t m = 0; m < ref.springs.size(); ++m) {
    springs.index.push_back(static_cast<int>(m));
    springs.stiffness.push_back(ref.stiffness.size() == 1 ? ref.stiffness[0] : ref.stiffness[m]);
  }
  return springs;
}

// The solvers stop between Newton iterations; a stopped solve has no reference to keep.
void StopIfInterrupted(const EquilibriumSummary& summary) {
  if (summary.termination == Termination::kInterrupted) throw Interrupted();
}

// The MSS reference's solvers for one set of free nodes: the ordinary solve, and Newton steps
// that continue down to round-off after it (a few more iterations, once per scene).
struct MssReferenceSolvers {
  EquilibriumSolver solver;
  EquilibriumSolver polisher;

  static EquilibriumOptions SolveOptions(const EquilibriumOptions& options) {
    EquilibriumOptions out = options;
    out.max_iterations = std::max(options.max_iterations, kReferenceMaxIterations);
    return out;
  }
  static EquilibriumOptions PolishOptions(const EquilibriumOptions& options) {
    EquilibriumOptions out = options;
    out.relative_force_tolerance = 0.0;
    out.roundoff_force_tolerance = 1e-16;
    out.max_iterations = 4;
    return out;
  }
  MssReferenceSolvers(const SpringGeometry& geometry, const FreeNodes& free,
                      const EquilibriumOptions& options, Interruption* interruption)
      : solver(geometry, free, SolveOptions(options)),
        polisher(geometry, free, PolishOptions(options)) {
    solver.set_interruption(interruption);
    polisher.set_interruption(interruption);
  }
};

// Throws when the load of case k is too small for double precision next to the springs.
void CheckLoadResolved(std::size_t k, const EquilibriumSummary& summary) {
  if (summary.tolerance <= kReferenceResolution) return;
  throw InputError(LoadCasePath(k),
                   "the load is too small for double precision: round-off in the reference "
                   "springs' forces is " +
                       NumberText(summary.tolerance) +
                       " of it (stiff springs at the loaded nodes hide the soft ones' forces), "
                       "so its equilibrium is not determined; scale the loads up (at least " +
                       NumberText(summary.tolerance / kReferenceResolution, 2) + " times)");
}

// How far round-off leaves the solved equilibrium of case k undetermined (measured with the
// first solver's tolerances: the polisher's are round-off's own); throws when it is no data.
void MeasureResolution(std::size_t k, const FreeNodes& free, EquilibriumSolver& solver,
                       const ActiveSprings& springs, int d, PreparedLoadCase& lc) {
  double norm2 = 0.0;
  for (std::size_t i = 0; i < free.free_index.size(); ++i) {
    if (free.free_index[i] >= 0) norm2 += lc.reference.segment(d * i, d).squaredNorm();
  }
  const EquilibriumSolver::Resolution resolution =
      solver.DisplacementResolution(springs, lc.reference);
  lc.reference_solve->stable = resolution.stable;
  lc.reference_solve->resolution =
      norm2 > 0.0 ? resolution.spread / std::sqrt(norm2) : (resolution.spread > 0.0 ? 1.0 : 0.0);
  if (std::isinf(resolution.spread)) {
    throw InputError(LoadCasePath(k),
                     "the reference's equilibrium is not determined: its tangent stiffness "
                     "there is singular" +
                         std::string(resolution.stable ? "" : " (an unstable equilibrium)") +
                         ", so any force imbalance, round-off's included, moves it freely");
  }
  if (lc.reference_solve->resolution > kReferenceUndetermined) {
    throw InputError(LoadCasePath(k),
                     "the reference's equilibrium is not determined in double precision: "
                     "round-off in its springs' forces leaves its displacements uncertain by " +
                         NumberText(lc.reference_solve->resolution, 2) +
                         " times their size (a load this small next to stiff springs, or a "
                         "nearly singular stiffness); scale the load up");
  }
}

// One load case of the MSS reference: solved, polished where that balances the forces better,
// and its resolution measured.
void SolveMssCase(std::size_t k, const FreeNodes& free, MssReferenceSolvers& solvers,
                  const ActiveSprings& springs, int d, PreparedLoadCase& lc) {
  const RestStability stability = solvers.solver.RestStabilityOf(springs);
  if (stability.modes > 0) {
    throw InputError("reference", "the reference MSS is a mechanism under " + LoadCasePath(k) +
                                      " (" + std::to_string(stability.modes) +
                                      " free modes): it cannot carry the load");
  }
  lc.reference = Vector::Zero(static_cast<Eigen::Index>(d * free.free_index.size()));
  const EquilibriumSummary summary =
      solvers.solver.Solve(springs, lc.force, lc.prescribed, lc.reference);
  StopIfInterrupted(summary);
  CheckLoadResolved(k, summary);
  if (!summary.converged()) {
    throw InputError("reference", "no equilibrium of the reference MSS found under " +
                                      LoadCasePath(k) + ": " + NotConvergedText(summary) +
                                      PrecisionLimitText(stability, springs));
  }
  // The reference's equilibria are data: every identification compares against them, and
  // strategy direct reads stiffness off their force balance, where a soft spring's force can
  // be 1e-8 of a stiff one's. A polished solution is kept only where it balances the forces
  // better.
  Vector polished = lc.reference;
  const EquilibriumSummary polish =
      solvers.polisher.Solve(springs, lc.force, lc.prescribed, polished);
  StopIfInterrupted(polish);
  lc.reference_solve = ReferenceSolve{summary.iterations, 1, summary.final_residual};
  if (polish.final_residual < summary.final_residual) {
    lc.reference = std::move(polished);
    lc.reference_solve->iterations += polish.iterations;
    lc.reference_solve->residual = polish.final_residual;
  }
  MeasureResolution(k, free, solvers.solver, springs, d, lc);
}

}  // namespace

void SolveMssReference(const Scene& scene, const std::vector<FreeNodes>& free_sets,
                       const EquilibriumOptions& solver_options,
                       std::vector<PreparedLoadCase>& load_cases, Interruption* interruption) {
  const Reference& ref = scene.reference;
  const SpringGeometry geometry(scene.dimension, scene.rest, ref.springs);
  const ActiveSprings springs = ReferenceSprings(ref);
  std::vector<MssReferenceSolvers> solvers;
  solvers.reserve(free_sets.size());
  for (const FreeNodes& free : free_sets)
    solvers.emplace_back(geometry, free, solver_options, interruption);
  for (std::size_t k = 0; k < load_cases.size(); ++k) {
    ThrowIfInterrupted(interruption);
    PreparedLoadCase& lc = load_cases[k];
    SolveMssCase(k, free_sets[lc.free_set], solvers[lc.free_set], springs, scene.dimension, lc);
  }
}

void SolveFemReference(const Scene& scene, const std::vector<FreeNodes>& free_sets,
                       std::vector<PreparedLoadCase>& load_cases, Interruption* interruption) {
  const fem::FemModel model = fem::FemModel::Build(scene);
  std::vector<fem::FemEquilibriumSolver> solvers;
  solvers.reserve(free_sets.size());
  for (const FreeNodes& free : free_sets) {
    solvers.emplace_back(model, free);
    solvers.back().set_interruption(interruption);
  }
  for (std::size_t k = 0; k < load_cases.size(); ++k) {
    PreparedLoadCase& lc = load_cases[k];
    const fem::FemSolveSummary summary =
        solvers[lc.free_set].Solve(lc.force, lc.prescribed, lc.reference);
    if (!summary.converged()) {
      throw InputError("reference",
                       "the FEM reference under " + LoadCasePath(k) + ": " + summary.message);
    }
    lc.reference_solve =
        ReferenceSolve{summary.iterations, summary.load_steps, summary.final_residual};
  }
}

void TakePositionsReference(const Scene& scene, const std::vector<FreeNodes>& free_sets,
                            double tolerance, std::vector<PreparedLoadCase>& load_cases) {
  const int d = scene.dimension;
  for (std::size_t k = 0; k < load_cases.size(); ++k) {
    PreparedLoadCase& lc = load_cases[k];
    lc.reference = scene.reference.positions[k] - scene.rest;
    const FreeNodes& free = free_sets[lc.free_set];
    for (int i = 0; i < scene.node_count(); ++i) {
      if (free.free_index[i] >= 0) continue;
      if ((lc.reference.segment(d * i, d) - lc.prescribed.segment(d * i, d)).norm() > tolerance) {
        throw InputError(
            "reference.positions[" + std::to_string(k) + "][" + std::to_string(i) + "]",
            "node " + std::to_string(i) + " is constrained in " + LoadCasePath(k) +
                " but its reference position differs from the prescribed one");
      }
      lc.reference.segment(d * i, d) = lc.prescribed.segment(d * i, d);
    }
  }
}

}  // namespace springfit
