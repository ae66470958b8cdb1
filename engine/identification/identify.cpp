#include "engine/identification/identify.h"

#include <cstdio>

#include "engine/identification/strategy.h"

namespace springfit {
namespace {

std::string StopMessage(const IdentificationResult& r) {
  char buf[200];
  const double target = std::max(r.options.target_normalized_error, kExactNormalizedError);
  switch (r.stop) {
    case StopReason::kTargetReached:
      std::snprintf(buf, sizeof buf, "the normalised error %.3g reached the target (<= %.3g)",
                    r.evaluation.normalized_error, target);
      break;
    case StopReason::kGenerationLimit:
      std::snprintf(buf, sizeof buf, "the generation limit (%d) was reached; normalised error %.3g",
                    r.options.max_generations, r.evaluation.normalized_error);
      break;
    case StopReason::kCancelled:
      std::snprintf(buf, sizeof buf,
                    "stopped on request after %d generations; the best so far is kept",
                    r.generations);
      break;
    case StopReason::kTimeLimit:
      std::snprintf(
          buf, sizeof buf,
          "the time limit (%.3g s) was reached after %d generations; normalised error %.3g",
          r.options.max_seconds, r.generations, r.evaluation.normalized_error);
      break;
    case StopReason::kStalled:
      std::snprintf(
          buf, sizeof buf,
          "no improvement for %d generations (best found in generation %d); normalised error %.3g",
          r.options.stall_generations, r.best_generation, r.evaluation.normalized_error);
      break;
    case StopReason::kCompleted:
      std::snprintf(buf, sizeof buf,
                    "direct ran to its end; normalised error %.3g, above the target (<= %.3g)",
                    r.evaluation.normalized_error, target);
      break;
  }
  return buf;
}

}  // namespace

IdentificationResult RunIdentification(const Problem& problem, const SearchOptions& options,
                                       const RunContext& context) {
  return RunIdentification(problem, options, context, *MakeStrategy(options.strategy));
}

IdentificationResult RunIdentification(const Problem& problem, const SearchOptions& options,
                                       const RunContext& context,
                                       const IdentificationStrategy& strategy) {
  // Before the run's clock starts (it starts inside the strategy): not part of its time.
  IdentifiabilityReport identifiability = AnalyseIdentifiability(problem);
  std::optional<fem::BaselineReport> baseline = fem::EvaluateClosedFormBaseline(problem);
  IdentificationResult r = strategy.Run(problem, options, context);
  r.identifiability = std::move(identifiability);
  r.baseline = std::move(baseline);
  r.springs = problem.SpringsOfGenome(r.best);
  r.difference = problem.CompareWithReference(r.best);
  if (r.stiffness.empty()) r.stiffness.assign(r.springs.size(), problem.training_stiffness());
  r.stop_message = StopMessage(r);
  return r;
}

}  // namespace springfit
