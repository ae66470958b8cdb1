#include "engine/identification/identify.h"

#include <string>

#include <fmt/format.h>

#include "engine/genome/gene_weights.h"
#include "engine/identification/as_simulated.h"
#include "engine/identification/run_bounds.h"
#include "engine/identification/run_monitor.h"
#include "engine/identification/strategy.h"
#include "engine/identification/verdict.h"
#include "engine/model/equilibrium.h"
#include "engine/problem/baseline_evaluation.h"
#include "engine/problem/force_balance.h"
#include "engine/runtime/input_error.h"
#include "engine/runtime/number_text.h"

namespace springfit {
namespace {

// The load cases without equilibrium and why, e.g. "load_cases[1]: the line search found no
// decrease ...".
std::string NoEquilibriumCases(const Evaluation& e) {
  std::string text;
  for (std::size_t k = 0; k < e.load_cases.size(); ++k) {
    const EquilibriumSummary& s = e.load_cases[k].solve;
    if (s.termination != Termination::kNotConverged) continue;
    if (!text.empty()) text += "; ";
    text += LoadCasePath(k) + ": " + NotConvergedText(s);
  }
  return text;
}

// What limited strategy direct, and what to try: springs the loads do not stretch, a force
// balance that did not converge, the strategies that search.
std::string DirectAdvice(const IdentificationResult& r) {
  if (!r.direct)
    return "; the search found no better model: try more generations or a larger "
           "population, or candidates that include the missing springs";
  const DirectResult& d = *r.direct;
  std::string text;
  if (!d.unseen.empty()) {
    text += "; the loads do not measurably stretch " + std::to_string(d.unseen.size()) + " of " +
            std::to_string(d.weights.size()) + " candidate springs (strain below " +
            NumberText(kUnseenStrain) +
            " in every load case), so the force balance "
            "cannot weigh them: use larger loads or more load cases";
  }
  if (!d.nnls.converged) {
    text += "; the force balance's non-negative least squares did not converge in " +
            std::to_string(d.nnls.iterations) +
            " rounds (nearly dependent springs: nearly collinear nodes, or too few load cases)";
  }
  return text +
         "; strategy hybrid searches from direct's model and keeps only models that "
         "carry the loads";
}

std::string StopMessage(const IdentificationResult& r) {
  // (A run stopped before its strategy had a model has its message from StoppedBeforeAModel.)
  if (r.trace.empty() && r.direct_phase &&
      (r.stop == StopReason::kCancelled || r.stop == StopReason::kTimeLimit))
    return fmt::format(
        "{} during the first generation: the direct phase's topology is kept",
        r.stop == StopReason::kCancelled ? "stopped on request" : "time limit reached");
  const double target = std::max(r.options.target_normalized_error, kExactNormalizedError);
  const double e = r.evaluation.normalized_error;
  switch (r.stop) {
    case StopReason::kTargetReached:
      return fmt::format("the normalised error {:.3g} reached the target (<= {:.3g})", e, target);
    case StopReason::kGenerationLimit:
      return fmt::format("the generation limit ({}) was reached; normalised error {:.3g}",
                         r.options.max_generations, e);
    case StopReason::kCancelled:
      return fmt::format("stopped on request after {} generations; the best so far is kept",
                         r.generations);
    case StopReason::kTimeLimit:
      return fmt::format(
          "the time limit ({:.3g} s) was reached after {} generations; normalised error {:.3g}",
          r.options.max_seconds, r.generations, e);
    case StopReason::kStalled:
      return fmt::format(
          "no improvement for {} generations (best found in generation {}); normalised error "
          "{:.3g}",
          r.options.stall_generations, r.best_generation, e);
    case StopReason::kCompleted:
      return fmt::format("ran to its end; normalised error {:.3g}", e);
    case StopReason::kNotReproduced:
      return fmt::format(
                 "direct's model does not reproduce the reference: normalised error {:.3g}, "
                 "above the target (<= {:.3g})",
                 e, target) +
             DirectAdvice(r);
    case StopReason::kMechanism:
      return fmt::format(
                 "the best model found is a mechanism ({} free modes over the load cases): it "
                 "cannot carry the loads and is no answer",
                 r.evaluation.mechanism_modes) +
             DirectAdvice(r);
    case StopReason::kNoEquilibrium:
      return "the best model found has no equilibrium under some load case (" +
             NoEquilibriumCases(r.evaluation) + "): it is no answer" + DirectAdvice(r);
  }
  return "";
}

// A run stopped before its strategy had a model: a resumed run's checkpointed best; else, where
// strategy continuous would start from the closed-form baseline (an FEM reference), that
// baseline, named as such; else the empty topology (a mechanism: its evaluation is rest
// factorisations only); no new trace row.
IdentificationResult StoppedBeforeAModel(const Problem& problem, const SearchOptions& options,
                                         const RunContext& context, const RunMonitor& monitor,
                                         const std::optional<BaselineReport>& evaluated) {
  IdentificationResult r;
  r.options = options;
  r.stop = monitor.time_limit_reached() ? StopReason::kTimeLimit : StopReason::kCancelled;
  r.trace = context.trace;
  r.wall_seconds = monitor.SecondsSinceStart();
  const char* why = r.stop == StopReason::kCancelled ? "stopped on request" : "time limit reached";
  // (The baseline of an FEM reference, within the spring budget: the start the fit would have.)
  std::optional<std::vector<double>> baseline;
  if (ResolvedStrategy(options.strategy, problem.scene()) == Strategy::kContinuous &&
      problem.scene().reference.kind == Reference::Kind::kFem)
    baseline = BaselineGeneWeights(problem);
  if (baseline && (PresentSprings(*baseline) == 0 ||
                   (options.max_springs > 0 && PresentSprings(*baseline) > options.max_springs)))
    baseline.reset();
  if (context.resume_from && !context.resume_from->best.empty()) {
    const SearchState& s = *context.resume_from;
    r.best = s.best;
    r.generations = s.generation;
    r.best_generation = s.best_generation;
    r.counters = s.counters;
    r.stop_message = fmt::format(
        "{} before the resumed run's first step: the checkpoint's best (generation {}) is kept",
        why, s.best_generation);
  } else if (baseline) {
    r.best.assign(static_cast<std::size_t>(problem.gene_count()), 0);
    for (std::size_t g = 0; g < baseline->size(); ++g) {
      if (!((*baseline)[g] > 0.0)) continue;
      r.best[g] = 1;
      r.stiffness.push_back((*baseline)[g]);
    }
    r.stop_message = fmt::format(
        "{} before the fit began (during the analysis): the closed-form baseline ({} springs, "
        "van Gelder 1998 on the mesh edges), not fitted and not certified",
        why, r.stiffness.size());
    // Its error as the analysis measured it, when it got that far; else measured now (the
    // baseline's named cases: milliseconds on the examples, seconds at 10,000 nodes).
    if (evaluated && evaluated->converged) {
      r.evaluation.converged = true;
      r.evaluation.normalized_error = evaluated->normalized_error;
      r.evaluation.cost = evaluated->normalized_error * problem.reference_norm2();
    } else {
      r.evaluation = CostFunction(problem).Evaluate(problem.SpringsOfWeights(*baseline));
    }
    return r;
  } else {
    r.best.assign(static_cast<std::size_t>(problem.gene_count()), 0);
    r.stop_message = fmt::format("{} before any model was evaluated: no model found", why);
  }
  r.evaluation = CostFunction(problem).EvaluateGenome(r.best);
  return r;
}

}  // namespace

IdentificationResult RunIdentification(const Problem& problem, const SearchOptions& options,
                                       const RunContext& context) {
  return RunIdentification(problem, options, context, *MakeStrategy(options.strategy, problem));
}

IdentificationResult RunIdentification(const Problem& problem, const SearchOptions& requested,
                                       const RunContext& context,
                                       const IdentificationStrategy& strategy) {
  // `default` on a scene whose springs differ in stiffness runs direct, which then identifies
  // each one's (ResolvedStrategy: search.identify was unset, or asked for exactly that).
  SearchOptions options = requested;
  if (!(context.memory_share > 0.0 && context.memory_share <= 1.0))
    throw std::invalid_argument(
        fmt::format("RunContext.memory_share: {} (must be in (0, 1])", context.memory_share));
  CheckRunBounds(problem, options);
  if (ResolvedStrategy(options.strategy, problem.scene()) == Strategy::kDirect &&
      options.strategy == Strategy::kDefault)
    options.identify = Identify::kTopologyAndStiffness;
  RunMonitor monitor(context, options.max_seconds);
  IdentifiabilityReport identifiability;
  std::optional<BaselineReport> baseline;
  IdentificationResult r;
  try {
    // Before the run's clock starts (it starts inside the strategy): not part of its time.
    identifiability = Identifiability(problem, &monitor.interruption());
    const auto evaluating = std::chrono::steady_clock::now();
    baseline = EvaluateClosedFormBaseline(problem, &monitor.interruption());
    // A stopped run still evaluates the model it returns on the named cases (as long as this
    // evaluation of a model of the mesh's size): the time limit keeps room for it, with a
    // tenth of a second for the result's judgement and output.
    if (baseline) monitor.ReserveForClosing(SecondsSince(evaluating) + 0.1);
    r = strategy.Run(problem, options, context, monitor);
  } catch (const Interrupted&) {
    r = StoppedBeforeAModel(problem, options, context, monitor, baseline);
  }
  // Continuous identifies each spring's stiffness, whatever the resolved options said of
  // `default` (they do not know the reference).
  if (ResolvedStrategy(options.strategy, problem.scene()) == Strategy::kContinuous)
    r.options.identify = Identify::kTopologyAndStiffness;
  r.ran = ResolvedStrategy(options.strategy, problem.scene());
  r.identifiability = std::move(identifiability);
  r.baseline = std::move(baseline);
  // A run that ended by itself (not by request, time or target) with no answer says so
  // first, then why it ended.
  // (Whether or not the strategy wrote its own message: continuous always does.)
  if (r.stop != StopReason::kCancelled && r.stop != StopReason::kTimeLimit &&
      r.stop != StopReason::kTargetReached && (r.evaluation.mechanism || !r.evaluation.converged)) {
    const std::string ended = r.stop_message.empty() ? StopMessage(r) : r.stop_message;
    r.stop = r.evaluation.mechanism ? StopReason::kMechanism : StopReason::kNoEquilibrium;
    r.stop_message = StopMessage(r) + " (the run ended: " + ended + ")";
  }
  r.springs = problem.SpringsOfGenome(r.best);
  r.difference = problem.CompareWithReference(r.best);
  if (r.stiffness.empty()) r.stiffness.assign(r.springs.size(), problem.training_stiffness());
  // (A phase of its own, whose beats carry no fill: the strategy's fill refers to its own
  // state, which is gone once it has returned.)
  monitor.SetPhase("as_simulated");
  r.as_simulated = NamedCasesAsSimulated(problem, r, &monitor.interruption());
  if (r.stop_message.empty()) r.stop_message = StopMessage(r);
  r.outcome = JudgeResult(problem, r);
  return r;
}

}  // namespace springfit
