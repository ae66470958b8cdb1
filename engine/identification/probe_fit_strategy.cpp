// Strategy continuous on an FEM or MSS reference with a probe bank: the model fitted to the
// reference's whole response (engine/response/response_fit.h), certified on held-out probes,
// and returned only when it beats the closed-form baseline there (issue 31).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

#include "engine/fem/closed_form_baseline.h"
#include "engine/fit/stiffness_fit.h"
#include "engine/identification/strategy.h"
#include "engine/problem/baseline_evaluation.h"
#include "engine/problem/cost.h"
#include "engine/response/generalization.h"
#include "engine/wall_clock.h"

namespace springfit {

namespace {

bool Probeable(const Problem& problem, const SearchOptions& options) {
  return options.probes != 0 && problem.scene().reference.kind != Reference::Kind::kPositions;
}

// The closed-form baseline (on the mesh edges, whether or not they are all candidates), or
// `start` for an MSS reference, which has no closed-form model: its rest stiffness for the
// certificate, its springs for the nonlinear judgement (amplitude_judgement.h).
struct BaselineModel {
  SparseMatrix stiffness;
  response::SpringModel springs;
};
BaselineModel BaselineModelOf(const Problem& problem,
                              const std::optional<std::vector<double>>& on_genes,
                              const std::vector<double>& start) {
  const std::vector<double>* weights = on_genes ? &*on_genes : &start;
  if (!on_genes && problem.scene().reference.kind == Reference::Kind::kFem) {
    fem::ClosedFormModel closed = fem::VanGelderModel(problem.scene());
    return {response::SpringRestStiffness(problem.dimension(), problem.scene().rest, closed.springs,
                                          closed.stiffness),
            {std::move(closed.springs), std::move(closed.stiffness)}};
  }
  return {response::SpringRestStiffness(problem, *weights),
          response::ModelOfWeights(problem, *weights)};
}

// The certificate's judgement at the named loads' size and below, when the response is
// nonlinear. False when stopped: the amplitudes are then left empty (the run is ending).
bool JudgeAtAmplitudes(const Problem& problem, const response::ProbeBank& bank,
                       const std::vector<double>& weights, const response::SpringModel& baseline,
                       response::Generalization& certificate, Interruption* interruption,
                       WorkerPool* pool) {
  try {
    certificate.amplitudes =
        response::JudgeAtAmplitudes(problem, bank, response::ModelOfWeights(problem, weights),
                                    baseline, {}, interruption, pool);
    return true;
  } catch (const Interrupted&) {
    certificate.amplitudes.clear();
    return false;
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

std::optional<response::Generalization> CertifyOnProbes(
    const Problem& problem, const SearchOptions& options, const std::vector<double>& weights,
    const std::vector<double>& start, Interruption* interruption, WorkerPool* pool) {
  if (!Probeable(problem, options)) return std::nullopt;
  std::optional<std::vector<double>> baseline_weights;
  if (problem.scene().reference.kind == Reference::Kind::kFem)
    baseline_weights = BaselineGeneWeights(problem);
  const SparseMatrix reference_stiffness = response::ReferenceRestStiffness(problem);
  const response::ProbeOptions probe_options = ProbeOptionsOf(options);
  const response::ProbeBank bank =
      response::MakeProbeBank(problem, reference_stiffness, probe_options);
  const BaselineModel baseline = BaselineModelOf(problem, baseline_weights, start);
  response::Generalization g =
      response::Certify(problem, bank, reference_stiffness, weights, baseline.stiffness);
  g.named_weight = probe_options.named_weight;
  JudgeAtAmplitudes(problem, bank, weights, baseline.springs, g, interruption, pool);
  return g;
}

namespace {

// The start and prior of a probe fit, and the baseline its model is judged beside: the
// closed-form baseline where it is a model of the candidates (an FEM reference), else the
// training stiffness on every candidate.
struct ProbeFitBaseline {
  std::optional<std::vector<double>> on_genes;
  std::vector<double> start;
  BaselineModel model;
};

ProbeFitBaseline BaselineOf(const Problem& problem) {
  ProbeFitBaseline b;
  if (problem.scene().reference.kind == Reference::Kind::kFem)
    b.on_genes = BaselineGeneWeights(problem);
  b.start = b.on_genes ? *b.on_genes
                       : std::vector<double>(static_cast<std::size_t>(problem.gene_count()),
                                             problem.training_stiffness());
  b.model = BaselineModelOf(problem, b.on_genes, b.start);
  return b;
}

response::ResponseFitOptions FitOptionsOf(const SearchOptions& options) {
  response::ResponseFitOptions o;
  o.probes = ProbeOptionsOf(options);
  o.max_springs = options.max_springs;
  o.max_spread = options.max_spread;
  // A strength set by the user is the one used; none (0) or auto: chosen on the choosing probes.
  if (!options.choose_regularization && options.regularization > 0.0)
    o.regularizations = {options.regularization};
  return o;
}

// The model a probe fit returns, and its certificate.
struct ProbeFitModel {
  std::vector<double> weights;
  response::Generalization certificate;
  bool stopped = false;  // during the fit: the start, judged
  // After the fit, during its nonlinear judgement: the fitted model, not judged at amplitudes.
  bool judgement_stopped = false;
  // When the baseline is returned: the fitted model's held-out errors it was refused on.
  response::ErrorSummary fitted_held_out;
};

// The fit, certified on the held-out probes; stopped, the start certified instead.
ProbeFitModel FitAndCertify(const Problem& problem, const response::ProbeBank& bank,
                            const SparseMatrix& reference_stiffness,
                            const ProbeFitBaseline& baseline,
                            const response::ResponseFitOptions& fit_options, RunMonitor& monitor,
                            const response::ResponseProgress& progress, WorkerPool* pool) {
  ProbeFitModel m;
  m.weights = baseline.start;
  try {
    response::ResponseFitResult fit =
        response::FitResponse(problem, bank, reference_stiffness, baseline.start, fit_options,
                              &monitor.interruption(), progress, pool);
    m.weights = fit.weights;
    m.certificate =
        response::Certify(problem, bank, reference_stiffness, m.weights, baseline.model.stiffness);
    m.certificate.fitted_to_probes = true;
    m.certificate.fit = std::move(fit);
  } catch (const Interrupted&) {
    m.stopped = true;
    m.certificate =
        response::Certify(problem, bank, reference_stiffness, m.weights, baseline.model.stiffness);
  }
  m.certificate.named_weight = fit_options.probes.named_weight;
  return m;
}

// The baseline guarantee on unseen loads: a model whose held-out E is not below the
// baseline's gives way to it (within the spring budget, when there is one).
void KeepBaselineGuarantee(const Problem& problem, const SearchOptions& options,
                           const response::ProbeBank& bank, const SparseMatrix& reference_stiffness,
                           const ProbeFitBaseline& baseline, ProbeFitModel& m) {
  const bool within_budget =
      baseline.on_genes &&
      (options.max_springs == 0 || PresentSprings(*baseline.on_genes) <= options.max_springs);
  if (m.stopped || !within_budget ||
      m.certificate.model_held_out.rms < m.certificate.baseline_held_out.rms)
    return;
  m.weights = *baseline.on_genes;
  m.fitted_held_out = m.certificate.model_held_out;
  response::Generalization judged =
      response::Certify(problem, bank, reference_stiffness, m.weights, baseline.model.stiffness);
  judged.fitted_to_probes = m.certificate.fitted_to_probes;
  judged.fit = std::move(m.certificate.fit);
  judged.named_weight = m.certificate.named_weight;
  judged.returned_baseline = true;
  m.certificate = std::move(judged);
}

// The stop message: the model's springs, probes and errors, or why the baseline was returned.
std::string ProbeFitMessage(const IdentificationResult& r, const ProbeFitModel& m) {
  const response::Generalization& c = m.certificate;
  char message[512];
  if (c.returned_baseline) {
    std::snprintf(message, sizeof message,
                  "the closed-form baseline (%d springs): the fitted model's held-out E (RMS over "
                  "%d probes) %.3g was not below the baseline's %.3g",
                  PresentSprings(m.weights), c.held_out, m.fitted_held_out.rms,
                  c.baseline_held_out.rms);
  } else {
    const char* stopped =
        r.stop == StopReason::kCompleted ? ""
        : m.judgement_stopped
            ? (r.stop == StopReason::kTimeLimit
                   ? "time limit reached during the nonlinear judgement (not judged at "
                     "amplitudes): "
                   : "stopped on request during the nonlinear judgement (not judged at "
                     "amplitudes): ")
        : r.stop == StopReason::kTimeLimit ? "time limit reached; the best so far: "
                                           : "stopped on request; the best so far: ";
    std::snprintf(message, sizeof message,
                  "%s%d springs fitted to %d probe loads on %d supports; held-out probes: "
                  "median E %.3g (baseline %.3g); named cases E %.3g",
                  stopped, PresentSprings(m.weights), c.fitted, c.supports, c.model_held_out.median,
                  c.baseline_held_out.median, std::sqrt(r.evaluation.normalized_error));
  }
  return message;
}

}  // namespace

namespace {

// The model as the run's genome and stiffness, and its one trace row; false when the caller's
// on_iteration asks to stop.
bool RecordModel(const Problem& problem, const std::vector<double>& weights, double wall_seconds,
                 const RunContext& context, RunMonitor& monitor, IdentificationResult& r) {
  const int genes = problem.gene_count();
  r.best.assign(static_cast<std::size_t>(genes), 0);
  for (int g = 0; g < genes; ++g) {
    if (weights[static_cast<std::size_t>(g)] > 0.0) {
      r.best[static_cast<std::size_t>(g)] = 1;
      r.stiffness.push_back(weights[static_cast<std::size_t>(g)]);
    }
  }
  TraceRow row;
  row.generation = static_cast<int>(r.trace.size());
  row.wall_seconds = wall_seconds;
  row.best_normalized_error = r.evaluation.normalized_error;
  row.best_cost = r.evaluation.cost;
  row.mean_cost = row.best_cost;
  r.trace.push_back(row);
  monitor.Reported();
  if (!context.on_iteration) return true;
  IterationState state;
  state.finished = true;
  state.best = &r.best;
  return context.on_iteration(row, state);
}

}  // namespace

IdentificationResult RunProbeFit(const Problem& problem, const SearchOptions& options,
                                 const RunContext& context, RunMonitor& monitor) {
  using Clock = std::chrono::steady_clock;
  const auto start_time = Clock::now();
  const auto since = [&] { return SecondsSince(start_time); };
  IdentificationResult r;
  r.options = options;
  r.trace = context.trace;
  const ProbeFitBaseline baseline = BaselineOf(problem);
  IdentificationResult::Continuous details;
  details.started_from_baseline = baseline.on_genes.has_value();

  // Progress: the fit's phase and its best choosing error so far.
  double current = std::numeric_limits<double>::quiet_NaN();
  std::string phase;
  const auto enter = [&](const std::string& name) {
    phase = name;
    monitor.SetPhase(phase, [&](ProgressBeat& beat) {
      beat.wall_seconds = since();
      beat.best_normalized_error = current * current;
    });
  };
  enter("probes");
  const response::ResponseProgress progress = [&](const char* name, double error) {
    current = error;
    if (phase != name) enter(name);
    if (monitor.TimeLimitPassed()) throw Interrupted();
  };

  // The bank, the fit and its certificate, the baseline guarantee, the nonlinear judgement.
  const response::ResponseFitOptions fit_options = FitOptionsOf(options);
  const SparseMatrix reference_stiffness = response::ReferenceRestStiffness(problem);
  const response::ProbeBank bank =
      response::MakeProbeBank(problem, reference_stiffness, fit_options.probes);
  std::unique_ptr<WorkerPool> own_pool;
  WorkerPool* pool = PoolOf(context, own_pool);
  ProbeFitModel m = FitAndCertify(problem, bank, reference_stiffness, baseline, fit_options,
                                  monitor, progress, pool);
  KeepBaselineGuarantee(problem, options, bank, reference_stiffness, baseline, m);
  if (!m.stopped && problem.response() == Response::kNonlinear) {
    enter("nonlinear");
    m.judgement_stopped = !JudgeAtAmplitudes(problem, bank, m.weights, baseline.model.springs,
                                             m.certificate, &monitor.interruption(), pool);
  }
  details.model_seconds = since();

  // The named cases, judged as every strategy's model is (engine/problem/cost.h), in the problem's
  // response.
  CostOptions cost_options;
  cost_options.solve_cases_of_mechanisms = true;
  CostFunction cost(problem, cost_options);
  r.evaluation = cost.Evaluate(problem.SpringsOfWeights(m.weights));
  details.start_normalized_error =
      cost.Evaluate(problem.SpringsOfWeights(baseline.start)).normalized_error;
  details.fit_normalized_error = r.evaluation.normalized_error;
  details.chosen = m.certificate.returned_baseline ? -1 : m.certificate.fit.chosen;
  details.regularization = m.certificate.fit.regularization;
  details.steps = m.certificate.fit.gauss_newton_accepted;

  const bool stopped = !RecordModel(problem, m.weights, since(), context, monitor, r) ||
                       m.stopped || m.judgement_stopped;
  r.wall_seconds = since();
  r.stop = stopped
               ? (monitor.time_limit_reached() ? StopReason::kTimeLimit : StopReason::kCancelled)
               : StopReason::kCompleted;
  r.stop_message = ProbeFitMessage(r, m);
  r.continuous = std::move(details);
  r.generalization = std::move(m.certificate);
  return r;
}

}  // namespace springfit
