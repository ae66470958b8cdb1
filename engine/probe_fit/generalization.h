// The certificate of a model on an FEM or MSS reference: how it does on loads it was not
// fitted to, beside the closed-form baseline, and the bound the stiffness pencil gives for
// every load on the user's supports (issue 31, "A certificate on every result").
#pragma once

#include <string>
#include <vector>

#include "engine/probe_fit/amplitude_judgement.h"
#include "engine/probe_fit/free_body.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/probe_fit/response_fit.h"
#include "engine/probe_fit/tool_pushes.h"

namespace springfit::response {

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

// The one reader of the held-out probes (probe_bank.h, HeldOutProbes): the certificate judges a
// model on them and on the named cases; nothing it returns can steer a fit or a choice except
// through a Generalization, which the strategies read after every choice is made.
class Certifier {
 public:
  // Keeps references to `problem`, `bank` and `reference_stiffness`; copies the held-out
  // probes and the named cases into the bank it judges on.
  Certifier(const Problem& problem, const ProbeBank& bank, const HeldOutProbes& held_out,
            const SparseMatrix& reference_stiffness);

  // Judges `model` (per-gene weights) and `baseline` (a rest stiffness) on the held-out probes
  // and the named cases, and bounds the model's pencil on the user's supports. Throws
  // Interrupted when `interruption` stops it (between solves and Lanczos iterations).
  Generalization Certify(const std::vector<double>& model, const SparseMatrix& baseline,
                         Interruption* interruption = nullptr) const;

  // The model and the baseline as nonlinear spring models on the same probes
  // (amplitude_judgement.h).
  std::vector<AmplitudeErrors> JudgeAtAmplitudes(const SpringModel& model,
                                                 const SpringModel& baseline,
                                                 const AmplitudeOptions& options = {},
                                                 Interruption* interruption = nullptr,
                                                 WorkerPool* pool = nullptr) const;

  // The held-out tool loads (families push and grasp, on every support), at depths that are
  // fractions of the named loads' size (tool_pushes.h): loads no fit and no choice sees.
  std::vector<ToolPushErrors> JudgeToolPushes(const SpringModel& model, const SpringModel& baseline,
                                              const ToolPushOptions& options = {},
                                              Interruption* interruption = nullptr,
                                              WorkerPool* pool = nullptr) const;

  int held_out() const { return held_out_; }

 private:
  const Problem& problem_;
  const ProbeBank& bank_;
  const SparseMatrix& reference_stiffness_;
  ProbeBank judged_;  // the named cases, then the held-out probes, each in the bank's order
  int named_ = 0;
  int held_out_ = 0;
};

}  // namespace springfit::response
