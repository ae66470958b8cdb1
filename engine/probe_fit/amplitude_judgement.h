// A model judged as the nonlinear model a simulator runs (docs/ARCHITECTURE.md, "Judging a
// model as the simulator runs it"): the probe fit matches the reference's response at rest, but
// under a load of the named cases' size the springs (which turn and stretch) leave the
// small-load limit, and so does a nonlinear reference (St. Venant-Kirchhoff or neo-Hookean FEM,
// an MSS); a linear FEM reference is the small-load limit at every size, which is what it
// states of the tissue, and the springs are judged against it there as a simulator runs them. So
// the held-out probes and the named cases are applied again at fractions of their size (by default
// 25, 50 and 100% of the named loads: the generated probes are scaled like them, probe_bank.h) and
// solved to equilibrium, the reference with its own law and the model and the closed-form baseline
// as nonlinear spring models; E per probe as in probe_evaluation.h, summarised per amplitude.
//
// A probe the reference has no equilibrium for at an amplitude (a load beyond what it carries,
// buckling) is left out at that amplitude and counted; a model without an equilibrium there (a
// mechanism on the probe's support, or Newton's failure) has E infinite.
#pragma once

#include <string>
#include <vector>

#include "engine/api/probe_fit_report.h"
#include "engine/probe_fit/nonlinear_solves.h"
#include "engine/probe_fit/probe_bank.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/runtime/interruption.h"
#include "engine/runtime/worker_pool.h"

namespace springfit::response {

struct AmplitudeOptions {
  // Fractions of the named loads' size, each in (0, 20], ascending.
  std::vector<double> amplitudes = {0.25, 0.5, 1.0};
  // Probes judged at most (evenly spread over the bank), >= 1: each is three nonlinear solves
  // per amplitude.
  int max_probes = 48;

  // Throws std::invalid_argument naming the field, its value and the rule.
  void Validate(const std::string& owner = "AmplitudeOptions") const;
};

// Per amplitude, on the probes of `judged` (the certificate's: the held-out probes and the named
// cases, Certifier); empty when the reference is positions.
// Throws Interrupted when `interruption` stops it (checked between probes). With a pool the
// probes run in parallel, with the same result.
std::vector<AmplitudeErrors> JudgeAtAmplitudes(const Problem& problem, const ProbeBank& judged,
                                               const SpringModel& model,
                                               const SpringModel& baseline,
                                               const AmplitudeOptions& options = {},
                                               Interruption* interruption = nullptr,
                                               WorkerPool* pool = nullptr);

}  // namespace springfit::response
