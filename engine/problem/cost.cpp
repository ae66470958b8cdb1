#include "engine/problem/cost.h"

#include <algorithm>
#include <utility>

#include "engine/model/equilibrium.h"

namespace springfit {
namespace {

constexpr double kNotConvergedPenalty = 1.5 * kPenaltyBase;

// Sum over the free nodes of |u - reference|^2.
double SquaredError(const FreeNodes& free, int d, const Vector& u, const Vector& reference) {
  double cost = 0.0;
  for (int i = 0; i < static_cast<int>(free.free_index.size()); ++i) {
    if (free.free_index[i] >= 0)
      cost += (u.segment(d * i, d) - reference.segment(d * i, d)).squaredNorm();
  }
  return cost;
}

// The penalties of the cases with a mechanism or without an equilibrium, per load case (so the
// breakdown shows where the topology failed), and the evaluation's totals.
void Penalize(const Problem& p, double stable_cost, Evaluation& e) {
  for (std::size_t k = 0; k < p.load_cases().size(); ++k) {
    LoadCaseEvaluation& out = e.load_cases[k];
    const double norm2 = p.load_cases()[k].reference_norm2 > 0.0 ? p.load_cases()[k].reference_norm2
                                                                 : p.reference_norm2();
    if (out.solve.termination == Termination::kMechanism) {
      out.normalized_error = kPenaltyBase * (1.0 + out.solve.mechanism_modes);
      out.cost = out.normalized_error * norm2;
    } else if (out.solve.termination == Termination::kNotSolved) {
      out.normalized_error = 0.0;  // the verdict is another case's
      out.cost = 0.0;
    } else if (!out.solve.converged()) {
      out.normalized_error = kNotConvergedPenalty;
      out.cost = out.normalized_error * norm2;
    }
  }
  if (e.mechanism) {
    e.normalized_error = kPenaltyBase * (1.0 + e.mechanism_modes);
  } else if (!e.converged) {
    e.normalized_error = kNotConvergedPenalty;
  } else {
    e.normalized_error = std::min(stable_cost / p.reference_norm2(), kPenaltyBase);
  }
  e.cost = e.converged && e.normalized_error < kPenaltyBase
               ? stable_cost
               : e.normalized_error * p.reference_norm2();
}

}  // namespace

struct CostFunction::Solvers {
  std::vector<EquilibriumSolver> per_free_set;  // one per Problem::free_sets()
  std::vector<RestStability> stability;         // per free set, for the current evaluation
};

CostFunction::CostFunction(const Problem& problem, CostOptions options)
    : problem_(&problem), options_(options), solvers_(std::make_unique<Solvers>()) {
  solvers_->per_free_set.reserve(problem.free_sets().size());
  EquilibriumOptions solver_options = problem.solver_options();
  if (options_.response) solver_options.response = *options_.response;
  for (const FreeNodes& free : problem.free_sets()) {
    solvers_->per_free_set.emplace_back(problem.candidates(), free, solver_options);
  }
}

CostFunction::~CostFunction() = default;
CostFunction::CostFunction(CostFunction&&) noexcept = default;
CostFunction& CostFunction::operator=(CostFunction&&) noexcept = default;

void CostFunction::set_interruption(Interruption* interruption) {
  for (EquilibriumSolver& solver : solvers_->per_free_set) solver.set_interruption(interruption);
}

Evaluation CostFunction::EvaluateGenome(const Genome& genome) {
  return EvaluateMask(problem_->MaskFromGenome(genome));
}

Evaluation CostFunction::EvaluateMask(const std::vector<std::uint8_t>& candidate_mask) {
  return Evaluate(problem_->SpringsFromMask(candidate_mask));
}

bool CostFunction::CheckStability(const ActiveSprings& springs) {
  // One rest factorisation per distinct set of constrained nodes.
  std::vector<RestStability>& stability = solvers_->stability;
  stability.assign(solvers_->per_free_set.size(), RestStability{});
  bool any_mechanism = false;
  for (std::size_t f = 0; f < stability.size(); ++f) {
    stability[f] = solvers_->per_free_set[f].RestStabilityOf(springs);
    any_mechanism = any_mechanism || stability[f].modes > 0;
  }
  return any_mechanism;
}

Evaluation CostFunction::Evaluate(const ActiveSprings& springs,
                                  std::vector<Vector>* displacements) {
  const Problem& p = *problem_;
  const int d = p.dimension();
  Evaluation e;
  e.load_cases.resize(p.load_cases().size());
  if (displacements) displacements->assign(p.load_cases().size(), Vector());

  const bool any_mechanism = CheckStability(springs);
  const std::vector<RestStability>& stability = solvers_->stability;

  double stable_cost = 0.0;
  for (std::size_t k = 0; k < p.load_cases().size(); ++k) {
    const PreparedLoadCase& lc = p.load_cases()[k];
    LoadCaseEvaluation& out = e.load_cases[k];
    const int modes = stability[lc.free_set].modes;
    out.solve.near_mechanism_modes = stability[lc.free_set].near_modes;
    if (modes > 0) {
      out.solve.termination = Termination::kMechanism;
      out.solve.mechanism_modes = modes;
      e.mechanism = true;
      e.converged = false;
      e.mechanism_modes += modes;
      continue;
    }
    if (any_mechanism && !options_.solve_cases_of_mechanisms) {
      out.solve.termination = Termination::kNotSolved;
      continue;
    }
    if (options_.warm_start == CostOptions::WarmStart::kReference) {
      u_ = lc.reference;
    } else {
      u_.setZero(lc.reference.size());
    }
    EquilibriumSolver& solver = solvers_->per_free_set[lc.free_set];
    out.solve = solver.Solve(springs, lc.force, lc.prescribed, u_);
    out.solve.near_mechanism_modes = stability[lc.free_set].near_modes;
    if (out.solve.termination == Termination::kInterrupted) {
      e.interrupted = true;
      e.converged = false;
      return e;
    }
    if (!out.solve.converged()) {
      e.converged = false;
      continue;
    }
    const double cost = SquaredError(p.free_sets()[lc.free_set], d, u_, lc.reference);
    out.cost = cost;
    // A case whose reference moves no free node is normalised by the whole reference instead.
    out.normalized_error =
        cost / (lc.reference_norm2 > 0.0 ? lc.reference_norm2 : p.reference_norm2());
    stable_cost += cost;
    if (displacements) (*displacements)[k] = u_;
  }

  Penalize(p, stable_cost, e);
  return e;
}

}  // namespace springfit
