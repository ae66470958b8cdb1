#include "engine/identification/as_simulated.h"

#include <cmath>
#include <limits>
#include <optional>
#include <vector>

#include "engine/fem/closed_form_baseline.h"
#include "engine/probe_fit/nonlinear_solves.h"

namespace springfit {
namespace {

constexpr double kNoEquilibrium = std::numeric_limits<double>::infinity();

// E of `springs` over `geometry` under the named cases with the spring law, as the cost measures
// it (engine/problem/cost.h): each case solved from the reference's equilibrium (near a model
// worth judging) with the load steps' chord steps, which refactorise only where Newton slows;
// infinite where some case has no equilibrium (a mechanism at rest, or no convergence).
// Throws Interrupted when stopped.
double NamedCasesError(const Problem& problem, const SpringGeometry& geometry,
                       const ActiveSprings& springs, Interruption* interruption) {
  const EquilibriumOptions options = response::LoadStepSolverOptions(problem);
  const int d = problem.dimension();
  std::vector<std::optional<EquilibriumSolver>> solvers(problem.free_sets().size());
  double cost = 0.0;
  for (const PreparedLoadCase& lc : problem.load_cases()) {
    const FreeNodes& free = problem.free_sets()[static_cast<std::size_t>(lc.free_set)];
    std::optional<EquilibriumSolver>& solver = solvers[static_cast<std::size_t>(lc.free_set)];
    if (!solver) {
      solver.emplace(geometry, free, options);
      solver->set_interruption(interruption);
      if (solver->RestMechanismModes(springs) > 0) return kNoEquilibrium;
    }
    Vector u = lc.reference;
    if (!solver->Solve(springs, lc.force, lc.prescribed, u).converged()) {
      ThrowIfInterrupted(interruption);  // stopped, rather than without equilibrium
      return kNoEquilibrium;
    }
    for (std::size_t i = 0; i < free.free_index.size(); ++i)
      if (free.free_index[i] >= 0)
        cost += (u.segment(d * static_cast<int>(i), d) -
                 lc.reference.segment(d * static_cast<int>(i), d))
                    .squaredNorm();
  }
  return std::sqrt(cost / problem.reference_norm2());
}

}  // namespace

std::optional<IdentificationResult::AsSimulated> NamedCasesAsSimulated(
    const Problem& problem, const IdentificationResult& result, Interruption* interruption) {
  if (problem.response() != Response::kLinear) return std::nullopt;
  if (interruption && interruption->Check()) return std::nullopt;
  ActiveSprings springs;
  for (std::size_t i = 0; i < result.springs.size(); ++i) {
    const int candidate = problem.CandidateIndex(result.springs[i]);
    if (candidate < 0 || !(result.stiffness[i] > 0.0)) continue;
    springs.index.push_back(candidate);
    springs.stiffness.push_back(result.stiffness[i]);
  }
  IdentificationResult::AsSimulated judged;
  try {
    judged.rms_error = NamedCasesError(problem, problem.candidates(), springs, interruption);
    const Scene& scene = problem.scene();
    if (scene.reference.kind == Reference::Kind::kFem) {
      const fem::ClosedFormModel baseline = fem::VanGelderModel(scene);
      const SpringGeometry geometry(scene.dimension, scene.rest, baseline.springs);
      ActiveSprings all;
      for (int m = 0; m < geometry.size(); ++m) {
        all.index.push_back(m);
        all.stiffness.push_back(baseline.stiffness[static_cast<std::size_t>(m)]);
      }
      judged.baseline_rms_error = NamedCasesError(problem, geometry, all, interruption);
    }
  } catch (const Interrupted&) {
    return std::nullopt;
  }
  return judged;
}

}  // namespace springfit
