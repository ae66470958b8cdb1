#include "engine/probe_fit/response_fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <optional>

#include "engine/fit/stiffness_fit.h"
#include "engine/probe_fit/gene_springs.h"
#include "engine/probe_fit/matrix_free_fit.h"
#include "engine/probe_fit/model_chooser.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/probe_fit/probe_objective.h"
#include "engine/runtime/options_check.h"
#include "engine/runtime/wall_clock.h"

namespace springfit::response {

void ResponseFitOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  probes.Validate(check.Nested("probes"));
  check.Require(!regularizations.empty(), "regularizations", 0.0, "at least one strength");
  for (double r : regularizations)
    check.Require(r >= 0.0 && std::isfinite(r), "regularizations", r, "every value >= 0");
  check.Require(InOpenUnit(prune_fraction), "prune_fraction", prune_fraction, "0 < value < 1");
  check.Require(dust >= 0.0 && dust < 1.0, "dust", dust, "0 <= value < 1");
  check.Require(max_spread == 0.0 || (max_spread > 1.0 && std::isfinite(max_spread)), "max_spread",
                max_spread, "value > 1 (0: none)");
  check.Require(max_springs >= 0, "max_springs", max_springs, "value >= 0 (0: none)");
  check.Require(min_lambda >= 0.0 && min_lambda < 1.0, "min_lambda", min_lambda, "0 <= value < 1");
  check.Require(lambda_slack >= 0.0, "lambda_slack", lambda_slack, "value >= 0");
  check.Require(steps_per_strength >= 1, "steps_per_strength", steps_per_strength, "value >= 1");
  check.Require(cg_iterations >= 1, "cg_iterations", cg_iterations, "value >= 1");
  check.Require(InOpenUnit(cg_tolerance), "cg_tolerance", cg_tolerance, "0 < value < 1");
  check.Require(diagonal_samples >= 1, "diagonal_samples", diagonal_samples, "value >= 1");
  lift.Validate(check.Nested("lift"));
  hold.Validate(check.Nested("hold"));
  check.Require(hold.weight == 0.0 || hold.target >= min_lambda, "hold.target", hold.target,
                "value >= min_lambda (the cuts hold the modes a little above it)");
  check.Require(continuation_patience >= 0, "continuation_patience", continuation_patience,
                "value >= 0 (0: every strength)");
  check.Require(soft_mode_rounds >= 0, "soft_mode_rounds", soft_mode_rounds, "value >= 0");
  check.Require(soft_modes_per_round >= 1, "soft_modes_per_round", soft_modes_per_round,
                "value >= 1");
}

namespace {

// The fit (a soft-mode round, or the lift) returned: with a spring budget the best within it; else
// the best on the choosing probes, a model that holds every mode preferred (ModelChooser).
std::size_t ChooseRound(const std::vector<ResponseFitResult::SoftModeRound>& path,
                        const ResponseFitOptions& options) {
  std::vector<CandidateModel> candidates;
  for (const ResponseFitResult::SoftModeRound& m : path)
    candidates.push_back({m.springs, m.select_error, m.lambda_min});
  return ModelChooser(options).Choose(candidates);
}

}  // namespace

ResponseFitResult FitResponse(const Problem& problem, const ProbeBank& bank,
                              const SparseMatrix& reference_stiffness,
                              const std::vector<double>& prior, const ResponseFitOptions& options,
                              Interruption* interruption, const ResponseProgress& progress,
                              WorkerPool* pool) {
  options.Validate();
  std::vector<ResponseFitResult> rounds{FitResponseMatrixFree(
      problem, bank, reference_stiffness, prior, options, interruption, progress, pool)};
  // 3. Soft modes: while the model leaves a mode of a user support below min_lambda, the load
  // along that mode joins the fitted probes and the fit runs again. The choosing probes are the
  // same in every round, so the rounds' models compare as the points of one path.
  std::vector<int> mode_probes;  // per refit, in its fit
  const int d = problem.dimension();
  // The reference factorised on each user support: the soft modes' and the lift's pencils.
  std::vector<std::pair<int, SupportSystem>> user;
  const auto user_supports = [&]() -> const std::vector<std::pair<int, SupportSystem>>& {
    if (user.empty()) {
      for (std::size_t s = 0; s < bank.supports.size(); ++s) {
        if (!bank.supports[s].user) continue;
        user.emplace_back(static_cast<int>(s), SupportSystem(d, bank.supports[s].constrained));
        user.back().second.Factorize(reference_stiffness);
      }
    }
    return user;
  };
  if (rounds.back().lambda_min < options.min_lambda && options.soft_mode_rounds > 0) {
    ProbeBank augmented = bank;
    for (int round = 0; round < options.soft_mode_rounds; ++round) {
      if (interruption && interruption->Check()) throw Interrupted();
      const SparseMatrix model = SpringRestStiffness(problem, rounds.back().weights);
      int added = 0;
      for (const auto& [s, reference] : user_supports()) {
        for (const SoftMode& mode :
             SoftModes(model, reference, options.min_lambda, options.soft_modes_per_round,
                       kLanczosIterations, interruption)) {
          AddSoftModeProbe(augmented, s, mode.shape, reference_stiffness, d);
          ++added;
        }
      }
      if (added == 0) break;
      mode_probes.push_back((mode_probes.empty() ? 0 : mode_probes.back()) + added);
      // (A whole fit again: started from the last model at its strength, the matrix-free fit's
      // steps lowered the fitted error and raised the choosing one on fem-block-3d, and the
      // soft modes stayed; its continuation from the prior is what lifts them.)
      rounds.push_back(FitResponseMatrixFree(problem, augmented, reference_stiffness, prior,
                                             options, interruption, progress, pool));
      if (rounds.back().lambda_min >= options.min_lambda) break;
    }
  }
  std::vector<ResponseFitResult::SoftModeRound> path;
  for (std::size_t i = 0; i < rounds.size(); ++i) {
    const ResponseFitResult& r = rounds[i];
    path.push_back({i == 0 ? 0 : mode_probes[i - 1], PresentSprings(r.weights), r.select_error,
                    r.lambda_min, false});
  }
  std::size_t chosen = ChooseRound(path, options);
  // 4. The mode lift of the model chosen, when it leaves a mode soft: one more candidate.
  if (options.lift_soft_modes && path[chosen].lambda_min < options.min_lambda &&
      path[chosen].select_error < kNoModel) {
    if (progress) progress("probe_lift", path[chosen].select_error);
    ResponseFitResult lifted = rounds[chosen];
    lifted.weights = BoundSpread(LiftSoftModes(problem, lifted.weights, PriorScale(prior),
                                               user_supports(), options.lift, interruption)
                                     .weights,
                                 options.max_spread);
    const SparseMatrix model = SpringRestStiffness(problem, lifted.weights);
    lifted.select_error = ChoosingError(bank, model, interruption);
    lifted.lambda_min = kNoModel;
    for (const auto& [s, reference] : user_supports())
      lifted.lambda_min = std::min(
          lifted.lambda_min,
          SmallestGeneralizedEigenvalue(model, reference, kLanczosIterations, interruption));
    path.push_back(
        {0, PresentSprings(lifted.weights), lifted.select_error, lifted.lambda_min, true});
    rounds.push_back(std::move(lifted));
    chosen = ChooseRound(path, options);
  }
  ResponseFitResult r = std::move(rounds[chosen]);
  r.soft_mode_rounds = std::move(path);
  r.soft_mode_chosen = static_cast<int>(chosen);
  return r;
}

}  // namespace springfit::response
