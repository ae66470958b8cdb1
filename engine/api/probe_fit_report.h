// What the probe fit and its certificate report: plain data, which the one result
// (engine/api/result.h) carries and every surface shows (run, the
// daemon, the dashboard, exports). The machinery that computes them is in the files each type
// names; this header holds no machinery, so that the result's readers do not reach it
// (docs/ARCHITECTURE.md, "The engine's surface").
#pragma once

#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace springfit::response {

// kMode: a load along a mode a fitted model left soft (AddSoftModeProbe), added by the fit
// itself (response_fit.h); never in the banks MakeProbeBanks returns, so never judged on.
enum class ProbeFamily { kPoint, kPatch, kBody, kNamed, kMode, kPush, kGrasp };
inline constexpr int kProbeFamilies = 7;
// The family's name, as results (proto/RUN.md), the summary and the verdict's doubts say it:
// "point", "patch", "body", "named", "mode", "push", "grasp".
const char* ProbeFamilyName(ProbeFamily family);
// A tool's load: imposed displacements on nodes the tool holds (push: one node, grasp: three),
// each probe on a support of its own.
constexpr bool IsToolFamily(ProbeFamily family) {
  return family == ProbeFamily::kPush || family == ProbeFamily::kGrasp;
}

// E over a set of probes (probe_evaluation.h, Summarize).
struct ErrorSummary {
  int probes = 0;
  double median = std::numeric_limits<double>::quiet_NaN();
  double p95 = std::numeric_limits<double>::quiet_NaN();  // the 95th percentile
  double rms = std::numeric_limits<double>::quiet_NaN();  // sqrt(mean E_p^2)
};

// E per family of the probes whose error is not NaN; families without any are left out
// (probe_evaluation.h, SummarizeByFamily).
struct FamilyErrors {
  ProbeFamily family = ProbeFamily::kPoint;
  ErrorSummary errors;
};

// The extreme generalised eigenvalues of a model's rest stiffness against the reference's on a
// support (probe_evaluation.h).
struct PencilExtremes {
  double lambda_min = 0.0;  // 0 when the model is not held by the support
  double lambda_max = 0.0;
  // max(1/lambda_min - 1, 1 - 1/lambda_max): infinity when lambda_min is 0.
  double Bound() const;
};

// A model judged as a nonlinear spring model at one fraction of the named loads' size
// (amplitude_judgement.h).
struct AmplitudeErrors {
  double amplitude = 0.0;
  ErrorSummary model;
  ErrorSummary baseline;
  int reference_failed = 0;  // probes left out: the reference has no equilibrium there
  // Judged probes whose equilibrium turns an element of the FEM mesh inside out
  // (InvertedElements): the model and the baseline fail them, whatever their E.
  int model_inverted = 0;
  int baseline_inverted = 0;
};

// The held-out tool loads at one depth (tool_pushes.h).
struct ToolPushErrors {
  double amplitude = 0.0;
  double depth = 0.0;  // in the scene's length
  ErrorSummary model;  // E over the free nodes
  ErrorSummary baseline;
  // |R - R_ref| / |R_ref|, R the tool's reaction (the elastic force on the pushed node).
  ErrorSummary model_force;
  ErrorSummary baseline_force;
  // The median of |R| / |R_ref|: below 1, the model feels too soft to the tool.
  double model_force_ratio = 0.0;
  double baseline_force_ratio = 0.0;
  int pushes = 0;            // the judged pushes (family push) with a reference equilibrium
  int grasps = 0;            // and grasps (family grasp)
  int reference_failed = 0;  // tool loads the reference has no equilibrium for, left out
  // Pushes whose equilibrium turns an FEM element inside out (InvertedElements): failed.
  int model_inverted = 0;
  int baseline_inverted = 0;
};

// What the nonlinear stage of the probe fit did (FitNonlinearResponse, matrix_free_fit.h).
struct NonlinearFitResult {
  std::vector<double> weights;     // per gene
  std::vector<double> amplitudes;  // NonlinearFitOptions::amplitudes
  int fitted_cases = 0;            // probe-amplitude pairs in the objective
  // Fitted probe-amplitude pairs the start model cannot hold (it folds there, or has no
  // equilibrium), left out of the objective (NonlinearCases::StartFrom).
  int fitted_left_out = 0;
  // Generated fitted probes left out to keep the stage within its memory
  // (NonlinearFitOptions::max_bytes), the bytes each probe-amplitude case holds and the bound
  // (0: none).
  int left_for_memory = 0;
  double case_bytes = 0.0;
  double max_bytes = 0.0;
  int choosing_cases = 0;  // and in the choice
  // The choosing error (NonlinearCases::ChoosingError) of `start` and of the returned model,
  // and their choosing cases without a stable equilibrium.
  double start_choosing_error = 0.0;
  double choosing_error = 0.0;
  int start_failed = 0;
  int failed = 0;
  // The closed-form baseline's, where it is a model of the candidates (NaN otherwise).
  double baseline_choosing_error = std::numeric_limits<double>::quiet_NaN();
  double regularization = 0.0;  // of the returned iterate (0 when it is `start`)
  int steps = 0;                // Gauss-Newton steps accepted
  double seconds = 0.0;
};

// What the probe fit did (FitResponse, response_fit.h).
struct ResponseFitResult {
  std::vector<double> weights;         // per gene, >= 0
  std::string method = "matrix-free";  // the fit that ran (one since the dense fit left)
  struct Point {
    int springs = 0;
    double select_error = 0.0;  // FamilyBalancedRms on the choosing probes
    double lambda_min = 0.0;    // the smallest over the user supports
  };
  // The continuation's chosen model, then, with a spring budget it exceeds, the best within the
  // budget; `chosen` is the one returned.
  std::vector<Point> path;
  int chosen = 0;
  double regularization = 0.0;
  // The strengths tried (ResponseFitOptions::regularizations, then any raised for min_lambda),
  // and per strength its model's choosing error and smallest eigenvalue.
  std::vector<double> regularizations;
  std::vector<double> regularization_select_errors;
  std::vector<double> regularization_lambda_min;
  double lambda_min = 0.0;    // of `weights`
  double select_error = 0.0;  // of `weights`
  int gauss_newton_accepted = 0;
  // Step 3: per fit (the first without soft-mode probes, then one per refit), the soft-mode
  // probes in it and its model's springs, choosing error and smallest eigenvalue; and which
  // fit's model was returned.
  // The last may be step 4's lift of the model then chosen (`lifted`; no probes).
  struct SoftModeRound {
    int probes = 0;
    int springs = 0;
    double select_error = 0.0;
    double lambda_min = 0.0;
    bool lifted = false;
  };
  std::vector<SoftModeRound> soft_mode_rounds;
  int soft_mode_chosen = 0;
  // Wall seconds: the continuation over the strengths, and the spring budget's sparsity paths.
  double seconds_continuation = 0.0;
  double seconds_budget = 0.0;
  // The nonlinear stage, where it ran (a nonlinear response: matrix_free_fit.h).
  std::optional<NonlinearFitResult> nonlinear;
};

// The certificate of a model (generalization.h, Certifier): how it does on loads it was not
// fitted to, beside the closed-form baseline, and the bound the stiffness pencil gives.
struct Generalization {
  // The bank.
  int probes = 0;  // in all, the named cases included
  int fitted = 0;
  int choosing = 0;
  int held_out = 0;
  int supports = 0;  // the user's and the drawn ones (a tool load's own support not counted)
  double named_weight = 0.0;
  // E on the held-out probes by family (point, patch, body), and on the named cases (rest
  // linear responses), of the model and of the baseline; and over every held-out probe.
  std::vector<FamilyErrors> model;
  std::vector<FamilyErrors> baseline;
  ErrorSummary model_held_out;
  ErrorSummary baseline_held_out;
  // The pencil (K_model, K_ref) on each user support, and the extremes over them.
  struct SupportPencil {
    std::string support;
    PencilExtremes model;
    PencilExtremes baseline;
  };
  std::vector<SupportPencil> pencils;
  double lambda_min = 0.0;
  double lambda_max = 0.0;
  double bound = 0.0;  // PencilExtremes::Bound of the extremes
  // The baseline's extremes over the same supports, for the same words beside the model's.
  PencilExtremes baseline_pencil;
  // The free-body pencil (free_body.h), of the model and of the baseline: it bounds every
  // support, the user's and any other a simulator holds the body by.
  PencilExtremes free_body;
  PencilExtremes baseline_free_body;
  // A nonlinear response: the model and the baseline as nonlinear spring models against the
  // nonlinear reference, per fraction of the named loads' size (amplitude_judgement.h); empty
  // for a linear one.
  std::vector<AmplitudeErrors> amplitudes;
  // A nonlinear response on an FEM reference: tool pushes (imposed displacements) on the first
  // user support, per depth (tool_pushes.h); empty otherwise.
  std::vector<ToolPushErrors> tool_pushes;
  // The fit (absent when the model was not fitted to probes: only judged on them).
  bool fitted_to_probes = false;
  ResponseFitResult fit;
  // The baseline was returned: the fitted model's choosing error (FamilyBalancedRms on the
  // choosing probes, never the held-out ones) was not below the baseline's.
  bool returned_baseline = false;
  double fitted_choosing_error = 0.0;    // when returned_baseline: the fitted model's
  double baseline_choosing_error = 0.0;  // and the baseline's
};

}  // namespace springfit::response
