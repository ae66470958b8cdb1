#include "engine/probe_fit/generalization.h"

#include <algorithm>

namespace springfit::response {

Certifier::Certifier(const Problem& problem, const ProbeBank& bank, const HeldOutProbes& held_out,
                     const SparseMatrix& reference_stiffness)
    : problem_(problem), bank_(bank), reference_stiffness_(reference_stiffness) {
  judged_.supports = bank.supports;
  judged_.boundary = bank.boundary;
  judged_.amplitude = bank.amplitude;
  for (const Probe& probe : bank.probes)
    if (probe.family == ProbeFamily::kNamed) judged_.probes.push_back(probe);
  named_ = static_cast<int>(judged_.probes.size());
  for (const Probe& probe : held_out.bank_.probes) judged_.probes.push_back(probe);
  held_out_ = held_out.size();
}

Generalization Certifier::Certify(const std::vector<double>& model, const SparseMatrix& baseline,
                                  Interruption* interruption) const {
  Generalization g;
  g.probes = static_cast<int>(bank_.probes.size()) + held_out_;
  for (const Support& support : bank_.supports) g.supports += support.tool() ? 0 : 1;
  for (const Probe& probe : bank_.probes) {
    g.fitted += probe.role == ProbeRole::kFit;
    g.choosing += probe.role == ProbeRole::kSelect;
  }
  g.held_out = held_out_;
  const std::vector<bool> every(judged_.probes.size(), true);
  const SparseMatrix k_model = SpringRestStiffness(problem_, model);
  const std::vector<double> model_errors =
      ProbeErrorsFor(judged_, k_model, every, interruption, {}, ToolSolves::kThroughBase);
  const std::vector<double> baseline_errors =
      ProbeErrorsFor(judged_, baseline, every, interruption, {}, ToolSolves::kThroughBase);
  g.model = SummarizeByFamily(judged_, model_errors);
  g.baseline = SummarizeByFamily(judged_, baseline_errors);
  const auto held_only = [&](const std::vector<double>& errors) {
    return Summarize(std::vector<double>(errors.begin() + named_, errors.end()));
  };
  g.model_held_out = held_only(model_errors);
  g.baseline_held_out = held_only(baseline_errors);
  bool first = true;
  for (const Support& support : bank_.supports) {
    if (!support.user) continue;
    Generalization::SupportPencil pencil;
    pencil.support = support.description;
    pencil.model =
        GeneralizedEigenvalueExtremes(k_model, reference_stiffness_, support.constrained,
                                      problem_.dimension(), kLanczosIterations, interruption);
    pencil.baseline =
        GeneralizedEigenvalueExtremes(baseline, reference_stiffness_, support.constrained,
                                      problem_.dimension(), kLanczosIterations, interruption);
    g.lambda_min =
        first ? pencil.model.lambda_min : std::min(g.lambda_min, pencil.model.lambda_min);
    g.lambda_max =
        first ? pencil.model.lambda_max : std::max(g.lambda_max, pencil.model.lambda_max);
    PencilExtremes& b = g.baseline_pencil;
    b.lambda_min =
        first ? pencil.baseline.lambda_min : std::min(b.lambda_min, pencil.baseline.lambda_min);
    b.lambda_max =
        first ? pencil.baseline.lambda_max : std::max(b.lambda_max, pencil.baseline.lambda_max);
    first = false;
    g.pencils.push_back(std::move(pencil));
  }
  g.bound = PencilExtremes{g.lambda_min, g.lambda_max}.Bound();
  const Scene& scene = problem_.scene();
  g.free_body = FreeBodyExtremes(k_model, reference_stiffness_, scene.dimension, scene.rest,
                                 kLanczosIterations, interruption);
  g.baseline_free_body = FreeBodyExtremes(baseline, reference_stiffness_, scene.dimension,
                                          scene.rest, kLanczosIterations, interruption);
  return g;
}

std::vector<AmplitudeErrors> Certifier::JudgeAtAmplitudes(const SpringModel& model,
                                                          const SpringModel& baseline,
                                                          const AmplitudeOptions& options,
                                                          Interruption* interruption,
                                                          WorkerPool* pool) const {
  return response::JudgeAtAmplitudes(problem_, judged_, model, baseline, options, interruption,
                                     pool);
}

std::vector<ToolPushErrors> Certifier::JudgeToolPushes(const SpringModel& model,
                                                       const SpringModel& baseline,
                                                       const ToolPushOptions& options,
                                                       Interruption* interruption,
                                                       WorkerPool* pool) const {
  return response::JudgeToolPushes(problem_, judged_, model, baseline, options, interruption, pool);
}

}  // namespace springfit::response
