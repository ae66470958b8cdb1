// Strategy continuous on an FEM or MSS reference with a probe bank: the model fitted to the
// reference's whole response (engine/probe_fit/response_fit.h), returned only when it beats the
// closed-form baseline on the choosing probes, and certified on the held-out probes, which
// nothing else reads (docs/ARCHITECTURE.md, "Probes by role").
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "engine/fem/closed_form_baseline.h"
#include "engine/fit/stiffness_fit.h"
#include "engine/identification/run_bounds.h"
#include "engine/identification/strategy.h"
#include "engine/probe_fit/generalization.h"
#include "engine/probe_fit/matrix_free_fit.h"
#include "engine/probe_fit/probe_objective.h"
#include "engine/problem/baseline_evaluation.h"
#include "engine/problem/cost.h"
#include "engine/runtime/input_error.h"
#include "engine/runtime/wall_clock.h"

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
    return {SpringRestStiffness(problem.dimension(), problem.scene().rest, closed.springs,
                                closed.stiffness),
            {std::move(closed.springs), std::move(closed.stiffness)}};
  }
  return {SpringRestStiffness(problem, *weights), response::ModelOfWeights(problem, *weights)};
}

response::ProbeOptions ProbeOptionsOf(const SearchOptions& options) {
  response::ProbeOptions o;
  o.seed = options.seed;
  if (options.probes > 0) o.count = options.probes;
  return o;
}

// A run's probes: the reference's rest stiffness, the banks (the fit's and the held-out one),
// and the certificate, the one reader of the held-out probes. Refers to itself: built in place.
class RunProbes {
 public:
  RunProbes(const Problem& problem, const response::ProbeOptions& options)
      : reference_stiffness_(ReferenceRestStiffness(problem)),
        banks_(response::MakeProbeBanks(problem, reference_stiffness_, options)),
        certifier_(problem, banks_.fit, banks_.held_out, reference_stiffness_) {}
  RunProbes(const RunProbes&) = delete;
  RunProbes& operator=(const RunProbes&) = delete;

  const SparseMatrix& reference_stiffness() const { return reference_stiffness_; }
  const response::ProbeBank& fit() const { return banks_.fit; }
  const response::Certifier& certifier() const { return certifier_; }

 private:
  SparseMatrix reference_stiffness_;
  response::ProbeBanks banks_;
  response::Certifier certifier_;
};

// The baseline guarantee on unseen loads, decided on the choosing probes (never the held-out
// ones, which only the certificate reads): a fitted model whose choosing error is not below the
// closed-form baseline's gives way to it, where the baseline is a model of the candidates
// within the spring budget. Sets the two errors when the baseline is chosen.
bool BaselineChosen(const Problem& problem, const SearchOptions& options,
                    const response::ProbeBank& bank, const std::vector<double>& fitted,
                    const std::optional<std::vector<double>>& baseline_on_genes,
                    const SparseMatrix& baseline,
                    const std::optional<response::NonlinearFitResult>& stage,
                    Interruption* interruption, response::Generalization& g) {
  if (!baseline_on_genes ||
      (options.max_springs > 0 && PresentSprings(*baseline_on_genes) > options.max_springs))
    return false;
  // (After a nonlinear stage, both as it judged them: at the load range's sizes.)
  const bool nonlinear = stage && stage->choosing_cases > 0;
  const double model_error =
      nonlinear ? stage->choosing_error
                : response::ChoosingError(bank, SpringRestStiffness(problem, fitted), interruption);
  const double baseline_error = nonlinear ? stage->baseline_choosing_error
                                          : response::ChoosingError(bank, baseline, interruption);
  if (model_error < baseline_error) return false;
  g.fitted_choosing_error = model_error;
  g.baseline_choosing_error = baseline_error;
  return true;
}

// A load range at most this many times the named loads' size: beyond it the reference has no
// equilibrium for most probes (the St Venant-Kirchhoff kidney lost a third of them at 3x).
constexpr double kMaxLoadScale = 20.0;

// The fractions of the named loads' size the nonlinear fit, the nonlinear judgement and the
// tool pushes run at: 25, 50 and 100% of the load range (SearchOptions::load_size, else the
// named loads' size, the bank's amplitude). Throws InputError on search.load_size beyond
// kMaxLoadScale times the named loads' size.
std::vector<double> LoadRangeAmplitudes(const SearchOptions& options,
                                        const response::ProbeBank& bank) {
  double scale = 1.0;
  if (options.load_size > 0.0 && bank.amplitude > 0.0) scale = options.load_size / bank.amplitude;
  if (scale > kMaxLoadScale)
    throw InputError("search.load_size",
                     fmt::format("{:.4g} is {:.3g} times the named loads' size ({:.4g}, their "
                                 "largest nodal displacement); at most {:.0f} times",
                                 options.load_size, scale, bank.amplitude, kMaxLoadScale));
  return {0.25 * scale, 0.5 * scale, scale};
}

// The judgement as the simulator runs the model across the load range, with nonlinear springs
// whatever the fit's response (docs/ARCHITECTURE.md, "Judging a model as the simulator runs
// it"). False when stopped: the amplitudes are then left empty (the run is ending).
bool JudgeAtAmplitudes(const Problem& problem, const RunProbes& probes,
                       const std::vector<double>& weights, const response::SpringModel& baseline,
                       const std::vector<double>& amplitudes, response::Generalization& certificate,
                       Interruption* interruption, WorkerPool* pool) {
  // (A linear reference is the small-load limit at every size, and the springs leave it more
  // the larger the load: they are judged at the range's full size alone, which is also what a
  // simulator applies. A nonlinear reference leaves it too, and is judged across the range.)
  const std::vector<double> sizes =
      problem.response() == Response::kLinear ? std::vector<double>{amplitudes.back()} : amplitudes;
  try {
    const response::SpringModel model = response::ModelOfWeights(problem, weights);
    response::AmplitudeOptions judged;
    judged.amplitudes = sizes;
    certificate.amplitudes =
        probes.certifier().JudgeAtAmplitudes(model, baseline, judged, interruption, pool);
    response::ToolPushOptions pushes;
    pushes.amplitudes = sizes;
    certificate.tool_pushes =
        probes.certifier().JudgeToolPushes(model, baseline, pushes, interruption, pool);
    return true;
  } catch (const Interrupted&) {
    certificate.amplitudes.clear();
    certificate.tool_pushes.clear();
    return false;
  }
}

}  // namespace

bool FitsToProbes(const Problem& problem, const SearchOptions& options) {
  // (A target error chooses by the named cases' E along their own path: sparsity_path.h.)
  return Probeable(problem, options) && options.target_error == 0.0;
}

std::optional<ProbeCertificate> CertifyOnProbes(const Problem& problem,
                                                const SearchOptions& options,
                                                const std::vector<double>& weights,
                                                const std::vector<double>& start,
                                                Interruption* interruption, WorkerPool* pool) {
  if (!Probeable(problem, options)) return std::nullopt;
  std::optional<std::vector<double>> baseline_weights;
  if (problem.scene().reference.kind == Reference::Kind::kFem)
    baseline_weights = BaselineGeneWeights(problem);
  const RunProbes probes(problem, ProbeOptionsOf(options));
  const BaselineModel baseline = BaselineModelOf(problem, baseline_weights, start);
  ProbeCertificate c;
  c.weights = weights;
  response::Generalization chosen;
  // (The guarantee returns the baseline only where the fit started from it: a start of the
  // training stiffness, where the baseline has no equilibrium, is not the baseline.)
  if (baseline_weights && *baseline_weights == start &&
      BaselineChosen(problem, options, probes.fit(), weights, baseline_weights, baseline.stiffness,
                     std::nullopt, interruption, chosen)) {
    c.weights = *baseline_weights;
    c.returned_baseline = true;
  }
  c.generalization = probes.certifier().Certify(c.weights, baseline.stiffness, interruption);
  c.generalization.named_weight = ProbeOptionsOf(options).named_weight;
  c.generalization.returned_baseline = c.returned_baseline;
  c.generalization.fitted_choosing_error = chosen.fitted_choosing_error;
  c.generalization.baseline_choosing_error = chosen.baseline_choosing_error;
  c.judgement_stopped = !JudgeAtAmplitudes(problem, probes, c.weights, baseline.springs,
                                           LoadRangeAmplitudes(options, probes.fit()),
                                           c.generalization, interruption, pool);
  return c;
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

// The nonlinear stage at the load range's sizes, within what the run may hold (its share of
// the machine's memory, RunContext::memory_share: half when it runs alone, as CheckRunBounds
// assumes) beside the probe fit's vectors; no bound where the machine's memory cannot be read.
response::NonlinearFitOptions NonlinearStageOptions(const Problem& problem,
                                                    const SearchOptions& options,
                                                    const RunContext& context,
                                                    const std::vector<double>& amplitudes) {
  response::NonlinearFitOptions nonlinear;
  nonlinear.amplitudes = amplitudes;
  if (const double machine = PhysicalMemoryBytes(); machine > 0.0)
    nonlinear.max_bytes =
        std::max(context.memory_share * machine - ProbeFitBytes(problem, options), 1.0);
  return nonlinear;
}

// Where a run stopped (on request or at its time limit), if it did.
enum class StoppedIn { kNowhere, kFit, kNonlinearFit, kCertificate, kJudgement };

// The model a probe fit returns, and its certificate (none when stopped before it was made).
struct ProbeFitModel {
  std::vector<double> weights;
  std::optional<response::Generalization> certificate;
  response::ResponseFitResult fit;
  bool fitted = false;  // the weights are the fit's (else the start's)
  bool start_is_baseline = false;
  bool returned_baseline = false;
  double fitted_choosing_error = 0.0;  // when returned_baseline
  double baseline_choosing_error = 0.0;
  StoppedIn stopped = StoppedIn::kNowhere;
};

// How far the rest-linear fit had got, from its progress reports (one for the start, then one
// per accepted Gauss-Newton step): a time limit that stops it says how long the fit would need.
// Times are on the run's clock, the one its time limit counts (RunMonitor::SecondsSinceStart).
struct FitPace {
  double started = 0.0;       // when the fit began (after the probe banks)
  int reports = 0;            // the start's report, then one per accepted step
  double first_report = 0.0;  // the start's: its linearisation done
  double last_report = 0.0;
  double stopped = 0.0;  // when the stop reached the fit
  int max_steps = 0;     // the continuation's at most: strengths x steps per strength

  void Reported(double seconds) {
    if (reports++ == 0) first_report = seconds;
    last_report = seconds;
  }

  // The continuation's seconds left at `now`, at most, at the pace of the steps it made; NaN
  // before its first step or past its at most (a refit's or a budget's path's steps).
  double Remaining(double now) const {
    const int steps = reports - 1;
    if (steps < 1 || steps >= max_steps) return std::numeric_limits<double>::quiet_NaN();
    const double per_step = (last_report - first_report) / steps;
    // (The time since the last report is the next step's, done in part: at most one step's.)
    return std::max(per_step * (max_steps - steps) - std::min(now - last_report, per_step), 0.0);
  }

  // "; it had made 4 Gauss-Newton steps in 12.3 s, of the continuation's at most 21: at that
  // pace up to 52 s more (a time limit above 71 s), and then its certificate".
  std::string Needed() const {
    const double spent = stopped - started;
    if (reports == 0)
      return fmt::format("; its first linearisation was not done after {:.3g} s", spent);
    const int steps = reports - 1;
    if (steps == 0) {
      const double at_least = max_steps * (stopped - first_report);
      return fmt::format(
          "; its first Gauss-Newton step was not done after {:.3g} s: the continuation's at most "
          "{} steps need more than {:.3g} s (a time limit above {:.3g} s), and then its "
          "certificate",
          spent, max_steps, at_least, stopped + at_least);
    }
    if (steps >= max_steps)
      return fmt::format(
          "; it had made {} Gauss-Newton steps in {:.3g} s (past the continuation's {}: a spring "
          "budget's path or a soft-mode refit), and then its certificate",
          steps, spent, max_steps);
    const double more = Remaining(stopped);
    return fmt::format(
        "; it had made {} Gauss-Newton steps in {:.3g} s, of the continuation's at most {}: at "
        "that pace up to {:.3g} s more (a time limit above {:.3g} s), and then its certificate",
        steps, spent, max_steps, more, stopped + more);
  }
};

// The fit; stopped, the start, uncertified (a stop ends the run within a second: certifying
// a large model is seconds of solves).
void Fit(const Problem& problem, const RunProbes& probes, const ProbeFitBaseline& baseline,
         const response::ResponseFitOptions& fit_options,
         const response::NonlinearFitOptions& nonlinear, RunMonitor& monitor,
         const response::ResponseProgress& progress, WorkerPool* pool, ProbeFitModel& m) {
  m.weights = baseline.start;
  m.start_is_baseline = baseline.on_genes.has_value();
  try {
    m.fit =
        response::FitResponse(problem, probes.fit(), probes.reference_stiffness(), baseline.start,
                              fit_options, &monitor.interruption(), progress, pool);
    m.weights = m.fit.weights;
    m.fitted = true;
  } catch (const Interrupted&) {
    m.stopped = StoppedIn::kFit;
    return;
  }
  // A nonlinear response: the rest-linear model continued to the equilibria at the load
  // range's sizes (docs/ARCHITECTURE.md, "The nonlinear fit"); stopped, the rest-linear model.
  if (problem.response() != Response::kNonlinear) return;
  try {
    m.fit.nonlinear = response::FitNonlinearResponse(
        problem, probes.fit(), probes.reference_stiffness(), m.fit.weights, fit_options, nonlinear,
        baseline.on_genes ? &*baseline.on_genes : nullptr, &monitor.interruption(), progress, pool);
    m.weights = m.fit.nonlinear->weights;
  } catch (const Interrupted&) {
    m.stopped = StoppedIn::kNonlinearFit;
  }
}

// The baseline guarantee (BaselineChosen), then the certificate of the model returned.
void ChooseAndCertify(const Problem& problem, const SearchOptions& options, const RunProbes& probes,
                      const ProbeFitBaseline& baseline,
                      const response::ResponseFitOptions& fit_options, RunMonitor& monitor,
                      ProbeFitModel& m) {
  if (m.stopped != StoppedIn::kNowhere) return;
  try {
    response::Generalization choice;
    if (BaselineChosen(problem, options, probes.fit(), m.weights, baseline.on_genes,
                       baseline.model.stiffness, m.fit.nonlinear, &monitor.interruption(),
                       choice)) {
      m.weights = *baseline.on_genes;
      m.returned_baseline = true;
      m.fitted_choosing_error = choice.fitted_choosing_error;
      m.baseline_choosing_error = choice.baseline_choosing_error;
    }
    response::Generalization g =
        probes.certifier().Certify(m.weights, baseline.model.stiffness, &monitor.interruption());
    g.fitted_to_probes = true;
    g.fit = m.fit;
    g.named_weight = fit_options.probes.named_weight;
    g.returned_baseline = m.returned_baseline;
    g.fitted_choosing_error = m.fitted_choosing_error;
    g.baseline_choosing_error = m.baseline_choosing_error;
    m.certificate = std::move(g);
  } catch (const Interrupted&) {
    m.stopped = StoppedIn::kCertificate;
  }
}

// The stop message: the model's springs, probes and errors, or why the baseline was returned,
// or where the run stopped and what it returns then.
std::string ProbeFitMessage(const IdentificationResult& r, const ProbeFitModel& m,
                            const FitPace& pace) {
  const bool timed_out = r.stop == StopReason::kTimeLimit;
  const char* why = timed_out ? "time limit reached" : "stopped on request";
  const int springs = PresentSprings(m.weights);
  switch (m.stopped) {
    case StoppedIn::kFit:
      return fmt::format(
          "{} during the fit: the start ({}, {} springs), not fitted and not certified{}", why,
          m.start_is_baseline ? "the closed-form baseline" : "the training stiffness", springs,
          timed_out ? pace.Needed() : "");
    case StoppedIn::kNonlinearFit:
      return fmt::format(
          "{} during the nonlinear fit: the rest-linear fitted model ({} springs), not fitted at "
          "the load range's sizes and not certified",
          why, springs);
    case StoppedIn::kCertificate:
      return fmt::format("{} during the certificate: {} ({} springs), not certified", why,
                         m.returned_baseline ? "the closed-form baseline" : "the fitted model",
                         springs);
    case StoppedIn::kJudgement:
    case StoppedIn::kNowhere:
      break;
  }
  const response::Generalization& c = *m.certificate;
  const std::string prefix =
      m.stopped == StoppedIn::kJudgement
          ? fmt::format("{} during the nonlinear judgement (not judged at amplitudes): ", why)
      : r.stop != StopReason::kCompleted ? fmt::format("{}; the model then made: ", why)
                                         : std::string();
  if (m.returned_baseline) {
    return prefix + fmt::format(
                        "the closed-form baseline ({} springs): the fitted model's choosing error "
                        "{:.3g} (over {} choosing probes) was not below the baseline's {:.3g}; "
                        "held-out probes: median E {:.3g}",
                        springs, m.fitted_choosing_error, c.choosing, m.baseline_choosing_error,
                        c.model_held_out.median);
  }
  return prefix + fmt::format(
                      "{} springs fitted to {} probe loads on {} supports; held-out probes: "
                      "median E {:.3g} (baseline {:.3g}); named cases E {:.3g}",
                      springs, c.fitted, c.supports, c.model_held_out.median,
                      c.baseline_held_out.median, std::sqrt(r.evaluation.normalized_error));
}

}  // namespace

namespace {

// The model as the run's genome and stiffness, and its one trace row; false when the caller's
// on_iteration asks to stop.
bool RecordModel(const Problem& problem, const std::vector<double>& weights, int steps,
                 double wall_seconds, const RunContext& context, RunMonitor& monitor,
                 IdentificationResult& r) {
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
  // The fit's steps, as the named-case fit's rows count them: the progress line's "fit step N"
  // then agrees with the result's steps (a new user's trial saw "fit step 0" beside 21).
  row.evaluations = steps;
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
  details.fitted_to_probes = true;

  // Progress: the fit's phase, its best choosing error so far and, in the continuation, the
  // time it has left at most.
  double current = std::numeric_limits<double>::quiet_NaN();
  std::string phase;
  FitPace pace;
  const auto enter = [&](const std::string& name) {
    phase = name;
    monitor.SetPhase(phase, [&](ProgressBeat& beat) {
      beat.wall_seconds = since();
      beat.best_normalized_error = current * current;
      if (phase == "probe_fit") beat.eta_seconds = pace.Remaining(monitor.SecondsSinceStart());
    });
  };
  enter("probes");
  const response::ResponseProgress progress = [&](const char* name, double error) {
    current = error;
    if (phase != name) enter(name);
    if (phase == "probe_fit") pace.Reported(monitor.SecondsSinceStart());
    if (monitor.TimeLimitPassed()) throw Interrupted();
  };

  // The banks, the fit, the baseline guarantee on the choosing probes, the certificate, the
  // nonlinear judgement.
  const response::ResponseFitOptions fit_options = FitOptionsOf(options);
  const RunProbes probes(problem, fit_options.probes);
  std::unique_ptr<WorkerPool> own_pool;
  WorkerPool* pool = PoolOf(context, own_pool);
  ProbeFitModel m;
  // (The load range is checked before the fit: a size out of bounds is refused at once.)
  const std::vector<double> amplitudes = LoadRangeAmplitudes(options, probes.fit());
  pace.started = monitor.SecondsSinceStart();
  pace.max_steps =
      static_cast<int>(fit_options.regularizations.size()) * fit_options.steps_per_strength;
  Fit(problem, probes, baseline, fit_options,
      NonlinearStageOptions(problem, options, context, amplitudes), monitor, progress, pool, m);
  pace.stopped = monitor.SecondsSinceStart();
  if (m.stopped == StoppedIn::kNowhere) enter("certificate");
  ChooseAndCertify(problem, options, probes, baseline, fit_options, monitor, m);
  if (m.certificate) {
    enter("nonlinear");
    if (!JudgeAtAmplitudes(problem, probes, m.weights, baseline.model.springs, amplitudes,
                           *m.certificate, &monitor.interruption(), pool))
      m.stopped = StoppedIn::kJudgement;
  }
  details.model_seconds = since();

  // The named cases, judged as every strategy's model is (engine/problem/cost.h), in the problem's
  // response.
  CostOptions cost_options;
  cost_options.solve_cases_of_mechanisms = true;
  CostFunction cost(problem, cost_options);
  r.evaluation = cost.Evaluate(problem.SpringsOfWeights(m.weights));
  // (Stopped during the fit, the model is the start: evaluated once.)
  details.start_normalized_error =
      m.weights == baseline.start
          ? r.evaluation.normalized_error
          : cost.Evaluate(problem.SpringsOfWeights(baseline.start)).normalized_error;
  details.fit_normalized_error = r.evaluation.normalized_error;
  details.chosen = m.returned_baseline || !m.fitted ? -1 : m.fit.chosen;
  details.regularization = m.fit.regularization;
  details.steps = m.fit.gauss_newton_accepted;

  const bool stopped =
      !RecordModel(problem, m.weights, details.steps, since(), context, monitor, r) ||
      m.stopped != StoppedIn::kNowhere;
  r.wall_seconds = since();
  r.stop = stopped
               ? (monitor.time_limit_reached() ? StopReason::kTimeLimit : StopReason::kCancelled)
               : StopReason::kCompleted;
  r.stop_message = ProbeFitMessage(r, m, pace);
  r.continuous = std::move(details);
  r.generalization = std::move(m.certificate);
  return r;
}

}  // namespace springfit
