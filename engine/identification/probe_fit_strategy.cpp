// Strategy continuous on an FEM or MSS reference with a probe bank: the model fitted to the
// reference's whole response (engine/response/response_fit.h), certified on held-out probes,
// and returned only when it beats the closed-form baseline there (issue 31).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

#include "engine/cost.h"
#include "engine/fem/closed_form_baseline.h"
#include "engine/fit/stiffness_fit.h"
#include "engine/identification/strategy.h"
#include "engine/response/generalization.h"

namespace springfit {

namespace {

bool Probeable(const Problem& problem, const SearchOptions& options) {
  return options.probes != 0 && problem.scene().reference.kind != Reference::Kind::kPositions;
}

// The closed-form baseline's rest stiffness (on the mesh edges, whether or not they are all
// candidates); `start` for an MSS reference, which has no closed-form model.
response::SparseMatrix BaselineStiffness(const Problem& problem,
                                         const std::optional<std::vector<double>>& on_genes,
                                         const std::vector<double>& start) {
  if (on_genes) return response::SpringRestStiffness(problem, *on_genes);
  if (problem.scene().reference.kind == Reference::Kind::kFem) {
    const fem::ClosedFormModel closed = fem::VanGelderModel(problem.scene());
    return response::SpringRestStiffness(problem.dimension(), problem.scene().rest, closed.springs,
                                         closed.stiffness);
  }
  return response::SpringRestStiffness(problem, start);
}

// The same baseline as springs, for the nonlinear judgement (amplitude_judgement.h).
response::SpringModel BaselineSprings(const Problem& problem,
                                      const std::optional<std::vector<double>>& on_genes,
                                      const std::vector<double>& start) {
  if (on_genes) return response::ModelOfWeights(problem, *on_genes);
  if (problem.scene().reference.kind == Reference::Kind::kFem) {
    const fem::ClosedFormModel closed = fem::VanGelderModel(problem.scene());
    return {closed.springs, closed.stiffness};
  }
  return response::ModelOfWeights(problem, start);
}

// The certificate's judgement at the named loads' size and below, when the response is
// nonlinear; left empty when stopped (the run is ending).
void JudgeAtAmplitudes(const Problem& problem, const response::ProbeBank& bank,
                       const std::vector<double>& weights, const response::SpringModel& baseline,
                       response::Generalization& certificate, Interruption* interruption,
                       WorkerPool* pool) {
  try {
    certificate.amplitudes =
        response::JudgeAtAmplitudes(problem, bank, response::ModelOfWeights(problem, weights),
                                    baseline, {}, interruption, pool);
  } catch (const Interrupted&) {
    certificate.amplitudes.clear();
  }
}

response::ProbeOptions ProbeOptionsOf(const SearchOptions& options) {
  response::ProbeOptions o;
  o.seed = options.seed;
  if (options.probes > 0) o.count = options.probes;
  return o;
}

}  // namespace

bool FitsToProbes(const Problem& problem, const SearchOptions& options) {
  // (A target error chooses by the named cases' E along their own path: sparsity_path.h.)
  return Probeable(problem, options) && options.target_error == 0.0;
}

std::optional<response::Generalization> CertifyOnProbes(const Problem& problem,
                                                        const SearchOptions& options,
                                                        const std::vector<double>& weights,
                                                        const std::vector<double>& start) {
  if (!Probeable(problem, options)) return std::nullopt;
  std::optional<std::vector<double>> baseline_weights;
  if (problem.scene().reference.kind == Reference::Kind::kFem)
    baseline_weights = fem::BaselineGeneWeights(problem);
  const response::SparseMatrix reference_stiffness = response::ReferenceRestStiffness(problem);
  const response::ProbeOptions probe_options = ProbeOptionsOf(options);
  const response::ProbeBank bank =
      response::MakeProbeBank(problem, reference_stiffness, probe_options);
  response::Generalization g =
      response::Certify(problem, bank, reference_stiffness, weights,
                        BaselineStiffness(problem, baseline_weights, start));
  g.named_weight = probe_options.named_weight;
  JudgeAtAmplitudes(problem, bank, weights, BaselineSprings(problem, baseline_weights, start), g,
                    nullptr, nullptr);
  return g;
}

IdentificationResult RunProbeFit(const Problem& problem, const SearchOptions& options,
                                 const RunContext& context, RunMonitor& monitor) {
  using Clock = std::chrono::steady_clock;
  const auto start_time = Clock::now();
  const auto since = [&] {
    return std::chrono::duration<double>(Clock::now() - start_time).count();
  };
  IdentificationResult r;
  r.options = options;
  r.trace = context.trace;
  const int genes = problem.gene_count();

  // The start and prior: the closed-form baseline where it is a model of the candidates.
  IdentificationResult::Continuous details;
  std::optional<std::vector<double>> baseline_weights;
  if (problem.scene().reference.kind == Reference::Kind::kFem)
    baseline_weights = fem::BaselineGeneWeights(problem);
  details.started_from_baseline = baseline_weights.has_value();
  const std::vector<double> start =
      baseline_weights
          ? *baseline_weights
          : std::vector<double>(static_cast<std::size_t>(genes), problem.training_stiffness());
  const response::SparseMatrix baseline_stiffness =
      BaselineStiffness(problem, baseline_weights, start);

  double current = std::numeric_limits<double>::quiet_NaN();
  std::string phase = "probes";
  monitor.SetPhase(phase, [&](ProgressBeat& beat) {
    beat.wall_seconds = since();
    beat.best_normalized_error = current * current;
  });
  response::ResponseFitOptions fit_options;
  fit_options.probes = ProbeOptionsOf(options);
  fit_options.max_springs = options.max_springs;
  // A strength set by the user is the one used; none (0) or auto: chosen on the choosing probes.
  if (!options.choose_regularization && options.regularization > 0.0)
    fit_options.regularizations = {options.regularization};
  bool stopped = false;
  std::vector<double> weights = start;
  response::Generalization certificate;
  const response::SparseMatrix reference_stiffness = response::ReferenceRestStiffness(problem);
  const response::ProbeBank bank =
      response::MakeProbeBank(problem, reference_stiffness, fit_options.probes);
  std::unique_ptr<WorkerPool> own_pool;
  WorkerPool* pool = PoolOf(context, own_pool);
  const response::ResponseProgress progress = [&](const char* name, double error) {
    current = error;
    if (phase != name) {
      phase = name;
      monitor.SetPhase(phase, [&](ProgressBeat& beat) {
        beat.wall_seconds = since();
        beat.best_normalized_error = current * current;
      });
    }
    if (monitor.TimeLimitPassed()) throw Interrupted();
  };
  try {
    response::ResponseFitResult fit =
        response::FitResponse(problem, bank, reference_stiffness, start, fit_options,
                              &monitor.interruption(), progress, pool);
    weights = fit.weights;
    certificate =
        response::Certify(problem, bank, reference_stiffness, weights, baseline_stiffness);
    certificate.fitted_to_probes = true;
    certificate.fit = std::move(fit);
  } catch (const Interrupted&) {
    stopped = true;
    certificate =
        response::Certify(problem, bank, reference_stiffness, weights, baseline_stiffness);
  }
  certificate.named_weight = fit_options.probes.named_weight;
  // The baseline guarantee on unseen loads (within the spring budget, when there is one).
  response::ErrorSummary fitted_held_out;
  const bool baseline_within_budget =
      baseline_weights &&
      (options.max_springs == 0 || PresentSprings(*baseline_weights) <= options.max_springs);
  if (!stopped && baseline_within_budget &&
      !(certificate.model_held_out.rms < certificate.baseline_held_out.rms)) {
    weights = *baseline_weights;
    fitted_held_out = certificate.model_held_out;
    response::Generalization judged =
        response::Certify(problem, bank, reference_stiffness, weights, baseline_stiffness);
    judged.fitted_to_probes = certificate.fitted_to_probes;
    judged.fit = std::move(certificate.fit);
    judged.named_weight = certificate.named_weight;
    judged.returned_baseline = true;
    certificate = std::move(judged);
  }
  if (!stopped) {
    JudgeAtAmplitudes(problem, bank, weights, BaselineSprings(problem, baseline_weights, start),
                      certificate, &monitor.interruption(), pool);
  }
  details.model_seconds = since();

  // The named cases, judged as every strategy's model is (cost.h), in the problem's response.
  CostOptions cost_options;
  cost_options.solve_cases_of_mechanisms = true;
  CostFunction cost(problem, cost_options);
  r.evaluation = cost.Evaluate(problem.SpringsOfWeights(weights));
  const Evaluation start_evaluation = cost.Evaluate(problem.SpringsOfWeights(start));
  details.start_normalized_error = start_evaluation.normalized_error;
  details.fit_normalized_error = r.evaluation.normalized_error;
  details.chosen = certificate.returned_baseline ? -1 : certificate.fit.chosen;
  details.regularization = certificate.fit.regularization;
  details.steps = certificate.fit.gauss_newton_accepted;
  r.best.assign(static_cast<std::size_t>(genes), 0);
  for (int g = 0; g < genes; ++g) {
    if (weights[static_cast<std::size_t>(g)] > 0.0) {
      r.best[static_cast<std::size_t>(g)] = 1;
      r.stiffness.push_back(weights[static_cast<std::size_t>(g)]);
    }
  }
  TraceRow row;
  row.generation = static_cast<int>(r.trace.size());
  row.wall_seconds = since();
  row.best_normalized_error = r.evaluation.normalized_error;
  row.best_cost = r.evaluation.cost;
  row.mean_cost = row.best_cost;
  r.trace.push_back(row);
  monitor.Reported();
  if (context.on_iteration) {
    IterationState state;
    state.finished = true;
    state.best = &r.best;
    if (!context.on_iteration(row, state)) stopped = true;
  }
  r.wall_seconds = since();
  r.stop = stopped
               ? (monitor.time_limit_reached() ? StopReason::kTimeLimit : StopReason::kCancelled)
               : StopReason::kCompleted;
  char message[512];
  const double e = std::sqrt(r.evaluation.normalized_error);
  if (certificate.returned_baseline) {
    std::snprintf(message, sizeof message,
                  "the closed-form baseline (%d springs): the fitted model's held-out E (RMS over "
                  "%d probes) %.3g was not below the baseline's %.3g",
                  PresentSprings(weights), certificate.held_out, fitted_held_out.rms,
                  certificate.baseline_held_out.rms);
  } else {
    std::snprintf(message, sizeof message,
                  "%s%d springs fitted to %d probe loads on %d supports; held-out probes: "
                  "median E %.3g (baseline %.3g); named cases E %.3g",
                  stopped ? (r.stop == StopReason::kTimeLimit ? "time limit reached; the best so "
                                                                "far: "
                                                              : "stopped on request; the best so "
                                                                "far: ")
                          : "",
                  PresentSprings(weights), certificate.fitted, certificate.supports,
                  certificate.model_held_out.median, certificate.baseline_held_out.median, e);
  }
  r.stop_message = message;
  r.continuous = std::move(details);
  r.generalization = std::move(certificate);
  return r;
}

}  // namespace springfit
