// The identification cost of a topology: how far its equilibria are from the reference's.
//
//   f = sum_k sum_i |X^R_ik - X^M_ik|^2            (Bianchi et al. 2003)
// over load cases k and the nodes i free in case k (constrained nodes match by construction),
// and the unit-free normalised error e = f / sum_k sum_i |u^R_ik|^2, u^R the reference's
// displacements. Scaling all lengths and forces of a scene by s scales f by s^2 and leaves e
// unchanged.
//
// A topology that cannot carry the loads gets no equilibrium and instead a finite, graded
// penalty on e, above every stable topology's error:
//   mechanism (rest stiffness singular):  e = kPenaltyBase * (1 + modes)
//   solver did not converge:              e = kPenaltyBase * 1.5
//   stable but e > kPenaltyBase:          e = kPenaltyBase (as useless as a near-mechanism)
// where `modes` sums the mechanism modes over all load cases: missing one spring scores
// better than missing twenty, so a search is not blind among mostly unstable genomes.
// The penalised cost is f = e * sum |u^R|^2, so cost and error stay proportional.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "engine/model/equilibrium.h"
#include "engine/problem/problem.h"

namespace springfit {

// Normalised error of a stable topology can reach this (displacements about 1000 times the
// reference's) before it is capped; mechanisms start at twice it.
inline constexpr double kPenaltyBase = 1e6;

struct LoadCaseEvaluation {
  double cost = 0.0;              // sum_i |X^R_i - X^M_i|^2 for this case (penalised if unstable)
  double normalized_error = 0.0;  // cost / sum_i |u^R_i|^2 of this case
  EquilibriumSummary solve;
};

struct Evaluation {
  double cost = 0.0;
  double normalized_error = 0.0;
  bool mechanism = false;   // some load case found a singular rest stiffness
  bool converged = true;    // every solve converged (false for mechanisms too)
  int mechanism_modes = 0;  // summed over load cases
  // Stopped by the CostFunction's Interruption before it was complete: cost and error mean
  // nothing (the caller abandons the evaluation).
  bool interrupted = false;
  std::vector<LoadCaseEvaluation> load_cases;
};

struct CostOptions {
  enum class WarmStart {
    kReference,  // start each solve from the reference's equilibrium (close for near-right
                 // topologies, the common case late in a search)
    kRest,       // start from the rest configuration
  };
  WarmStart warm_start = WarmStart::kReference;
  // A mechanism's penalty depends on its modes alone, known from the rest factorisations:
  // false skips the other load cases' solves (termination kNotSolved), which a search never
  // reads; true solves them for a per-case report (`springfit eval`).
  bool solve_cases_of_mechanisms = false;
  // The springs' law for these evaluations; none: the problem's (Problem::response). An export
  // predicts what a simulator computes, so it asks for kNonlinear whatever the problem's.
  std::optional<Response> response;
};

// Evaluates topologies of one Problem. Holds one EquilibriumSolver per distinct set of free
// nodes (their symbolic analysis was done once). Not thread-safe: one per thread; the
// Problem must outlive it.
class CostFunction {
 public:
  explicit CostFunction(const Problem& problem, CostOptions options = {});

  const Problem& problem() const { return *problem_; }
  // Checked between the Newton iterations of every solve (nullptr: never stopped).
  void set_interruption(Interruption* interruption);

  Evaluation EvaluateGenome(const Genome& genome);
  Evaluation EvaluateMask(const std::vector<std::uint8_t>& candidate_mask);
  // Any springs over the candidate geometry (per-spring stiffness allowed). When
  // `displacements` is given it receives the equilibrium displacements u per load case
  // (empty for a load case without equilibrium).
  Evaluation Evaluate(const ActiveSprings& springs, std::vector<Vector>* displacements = nullptr);

 private:
  // Stability first: fills stability_ (one rest factorisation per free set); true when some
  // set has a mechanism.
  bool CheckStability(const ActiveSprings& springs);

  const Problem* problem_;
  CostOptions options_;
  std::vector<EquilibriumSolver> solvers_;  // one per Problem::free_sets()
  std::vector<RestStability> stability_;    // per free set, for the current evaluation
  Vector u_;
};

}  // namespace springfit
