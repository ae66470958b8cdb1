// The certificate of a model on an FEM or MSS reference: how it does on loads it was not
// fitted to, beside the closed-form baseline, and the bound the stiffness pencil gives for
// every load on the user's supports (issue 31, "A certificate on every result").
#pragma once

#include <string>
#include <vector>

#include "engine/api/probe_fit_report.h"
#include "engine/probe_fit/amplitude_judgement.h"
#include "engine/probe_fit/free_body.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/probe_fit/response_fit.h"
#include "engine/probe_fit/tool_pushes.h"

namespace springfit::response {

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
