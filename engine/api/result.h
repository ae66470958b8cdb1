// The engine's public surface (engine/api/): the one result of an identification, whatever the
// strategy (a Ceres-style summary): why it stopped, the model it found (topology and per-spring
// stiffness), that model's evaluation against the reference, the trace, the counters, what the load
// cases can tell apart, the closed-form baseline of an FEM reference, and the details only one
// strategy has.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "engine/api/analysis.h"
#include "engine/api/checkpoint.h"
#include "engine/api/direct_result.h"
#include "engine/api/model.h"
#include "engine/api/problem.h"
#include "engine/api/search_options.h"
#include "engine/api/verdict.h"
#include "engine/runtime/trace.h"

namespace springfit {

struct IdentificationResult {
  SearchOptions options;            // as asked (options.strategy may be `default`)
  Strategy ran = Strategy::kPaper;  // the strategy that ran (`default` resolved)
  StopReason stop = StopReason::kGenerationLimit;
  std::string stop_message;  // one line: the stop reason's criterion, in words
  Genome best;
  std::vector<NodePair> springs;  // the best model's springs, in candidate order
  std::vector<double> stiffness;  // per spring of `springs`: identified, or the training stiffness
  Evaluation evaluation;          // of the best model, per load case
  // The named cases as the simulator runs the model, where the problem's response is linear
  // (`evaluation` is then the small-load limit's): E with the spring law, the model's and the
  // closed-form baseline's (engine/identification/as_simulated.h). Absent where the response is
  // nonlinear (`evaluation` is that already) or the run was stopped before it.
  struct AsSimulated {
    double rms_error = 0.0;  // infinite: no equilibrium under some case
    std::optional<double> baseline_rms_error;
  };
  std::optional<AsSimulated> as_simulated;

  // The verdict and the headline numbers, decided once at the end of RunIdentification
  // (verdict.h): every surface shows them and the exit codes follow them.
  Outcome outcome;
  // The model is an answer: it carries every load case, its equilibria were found, it
  // predicts the reference better than the rest shape does (normalised error < 1; a model
  // predicting no displacement at all scores exactly 1), and no load on the user's supports
  // finds a mode it leaves free. `springfit run` exits 10 otherwise.
  bool usable() const { return outcome.verdict != Verdict::kUnusable; }
  std::optional<TopologyDifference> difference;  // against the reference, when known
  int generations = 0;                           // bred after the initial population
  int best_generation = 0;                       // when the best was found
  EvaluationCounters counters;
  double wall_seconds = 0.0;
  std::vector<TraceRow> trace;
  // Strategies hybrid and default: the direct phase that seeded the GA (on a resumed run, as
  // the checkpoint's seed reports it).
  struct DirectPhase {
    double seconds = 0.0;
    double normalized_error = 0.0;  // of the direct topology (training stiffness)
    std::optional<TopologyDifference> difference;
  };
  std::optional<DirectPhase> direct_phase;
  // Strategy direct: its weights, thresholds, confidences and residuals.
  std::optional<DirectResult> direct;
  // Strategy continuous (and default on an FEM reference): the fit, the sparsity path and the
  // held-out error of the returned model.
  struct Continuous {
    struct Point {
      int springs = 0;
      double normalized_error = 0.0;
    };
    std::vector<Point> path;              // the trade-off: springs decrease along it
    int chosen = 0;                       // the path point the returned model was refitted from
    double fit_normalized_error = 0.0;    // the first fit's, on every candidate (path[0]'s)
    double start_normalized_error = 0.0;  // its start's (the closed-form baseline on FEM)
    bool started_from_baseline = false;
    // Fitted to probes (the probe fit), whether or not a stop left it without a certificate;
    // false on the named-case fit.
    bool fitted_to_probes = false;
    // Models refused by the final evaluation (no equilibrium from the reference's, or worse
    // than the start) before the returned one.
    int rejected = 0;
    int steps = 0;            // trust-region steps in all (fit, path, refit)
    std::int64_t solves = 0;  // tangent solves in all
    // Cross-validation over the load cases (sparsity_path.h, HeldOutErrors); absent with one
    // load case or when the run was stopped before it.
    std::optional<double> held_out_normalized_error;
    std::vector<double> held_out_per_case;
    // The fits' regularisation toward the start (StiffnessFitOptions::regularization), and
    // when `search.regularization` was `auto` the strengths tried with their held-out errors
    // (sparsity_path.h, ChooseRegularization; empty otherwise).
    double regularization = 0.0;
    // Wall seconds from the run's start to the returned model, before its held-out error.
    double model_seconds = 0.0;
    std::vector<double> regularization_strengths;
    std::vector<double> regularization_held_out;
  };
  std::optional<Continuous> continuous;
  // What the load cases can and cannot tell apart, analysed before the run's clock starts.
  IdentifiabilityReport identifiability;
  // An FEM reference: the closed-form MSS of its mesh, evaluated before the run (the model an
  // identification must beat, engine/fem/closed_form_baseline.h).
  std::optional<BaselineReport> baseline;
  // An FEM or MSS reference under strategy continuous with probes: the model judged on loads
  // it was not fitted to, beside the baseline (engine/api/probe_fit_report.h).
  std::optional<response::Generalization> generalization;

  // nullopt when the reference topology is unknown.
  std::optional<bool> exact() const {
    if (!difference) return std::nullopt;
    return difference->hamming() == 0;
  }
};

}  // namespace springfit
