// Tool loads: a boundary node (a push) or three neighbouring ones (a grasp) moved into the body
// to a depth, as a surgical tool does (an imposed displacement, not a force), the rest of the
// body free but for a support. A model is
// judged by the shape (E over the free nodes, as every probe) and by the force the tool feels
// (its reaction), which is what a haptic device renders: under an imposed displacement,
// scaling every stiffness leaves E unchanged, so E alone cannot judge the stiffness; the force
// can. The reference is solved with its own law (FEM), the model and the baseline with the
// simulator's spring law (docs/ARCHITECTURE.md, "Tool pushes").
//
// They are the probe bank's families push and grasp (probe_bank.h): fitted and chosen on like
// every family at the named loads' size; the certificate judges the held-out ones here, at depths
// across the load range, with the simulator's spring law and the reference's own.
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

struct ToolPushOptions {
  // Push depths as fractions of the named loads' size (the bank's amplitude: the largest nodal
  // displacement of its probes), each in (0, 20], ascending.
  std::vector<double> amplitudes = {0.25, 0.5, 1.0};
  // Tool loads (pushes and grasps) judged at most (>= 1), evenly spread over the bank's: each
  // is three nonlinear solves per depth.
  int max_tool_loads = 24;

  // Throws std::invalid_argument naming the field, its value and the rule.
  void Validate(const std::string& owner = "ToolPushOptions") const;
};

// Per depth, up to options.max_tool_loads of `bank`'s tool loads (families push and grasp, each at
// the bank's amplitude, scaled to the depth; a grasp's force is the sum over its held nodes).
// Empty for a bank without them (an MSS reference).
// Throws Interrupted when stopped; with a pool the pushes run in parallel, with the same result.
std::vector<ToolPushErrors> JudgeToolPushes(const Problem& problem, const ProbeBank& bank,
                                            const SpringModel& model, const SpringModel& baseline,
                                            const ToolPushOptions& options = {},
                                            Interruption* interruption = nullptr,
                                            WorkerPool* pool = nullptr);

}  // namespace springfit::response
