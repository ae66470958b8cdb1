// The engine's public surface (engine/api/). What a result is worth to its user, decided once
// (issue 33, "One verdict"): `springfit run`, `submit --wait`, `watch`, `result`, `list`, the
// dashboard, the daemon's log and /metrics all show this verdict and these numbers, and the exit
// codes follow it (README.md, "Exit codes").
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace springfit {

struct IdentificationResult;
class Problem;

enum class Verdict {
  kUsable,        // a model to use: every request met
  kUnmetRequest,  // a usable model, but a hard request (spring budget, target error) is not met
  kUnusable,      // no answer: a mechanism, no equilibrium, or no better than the rest shape
  // A usable model, every request met, that its certificate or its judgement as the simulator
  // runs it finds worse than the closed-form recipe somewhere a user will meet it (a bound, a
  // soft mode, unseen loads, the nonlinear springs at the load range, a tool's push, a folded
  // element), or fitted to a linear reference loaded past small strain.
  kDoubtful,
};

std::string_view VerdictName(Verdict verdict);  // "usable", "unmet_request", "unusable", "doubtful"
std::optional<Verdict> ParseVerdict(std::string_view name);

// The verdict and the headline numbers of one result.
struct Outcome {
  Verdict verdict = Verdict::kUsable;
  // kUnusable: why the model is no answer (one line); empty otherwise.
  std::string reason;
  // kUnmetRequest: each request not met, one line each (shown as WARNING lines).
  std::vector<std::string> unmet;
  // Each doubt about a usable model, one line each (WARNING lines): kDoubtful when there are
  // doubts and every request is met (an unmet request decides the verdict first).
  std::vector<std::string> doubts;

  // The model's springs (the result's `springs`), and the candidates no load case can see
  // (both nodes held in every case, ...) that an export adds at the training stiffness so that
  // the model is complete (io/spring_model.h).
  int springs = 0;
  int unseen_springs = 0;
  // E, the relative RMS nodal error on the named load cases; absent where the model has no
  // equilibrium in some case.
  std::optional<double> rms_error;
  // The closed-form baseline's E on the same cases (FEM references).
  std::optional<double> baseline_rms_error;
  // Where the fit's response is linear (the small-load limit: rms_error's), E on the same cases
  // as the simulator runs the springs (nonlinear, at the cases' own size; infinite: no
  // equilibrium under some case), the model's and the baseline's. Absent where the response is
  // nonlinear (rms_error is that already) or the run was stopped before it.
  std::optional<double> simulated_rms_error;
  std::optional<double> baseline_simulated_rms_error;
  // E on loads the model was not fitted to: the held-out probes' median and 95th percentile
  // (`held_out_of` "probes"), or the cross-validation over the load cases ("cases"), with the
  // baseline's median beside it where there is one. Absent: not measured (a positions
  // reference with one case, a run stopped early, a strategy that does not measure it).
  std::optional<double> held_out_rms_error;
  std::optional<double> held_out_p95;
  std::optional<double> baseline_held_out_rms_error;
  std::string held_out_of;

  // One line: "usable: 273 springs, E 0.048 (baseline 0.33), held-out probes E 0.049 (baseline
  // 0.20)"; with a linear response, E as simulated first and the small-load E beside it: "E
  // 0.0102 as simulated (baseline 0.0371), 0.0097 small-load (baseline 0.0361)"
  std::string Headline() const;
  // Where a doubtful verdict's reader finds what changes each doubt and what it costs, in the
  // words every summary uses (run, result, the dashboard, export); empty for other verdicts.
  std::string WhatToTry() const;
};

}  // namespace springfit
