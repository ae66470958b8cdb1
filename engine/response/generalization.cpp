#include "engine/response/generalization.h"

#include <algorithm>

namespace springfit::response {

Generalization Certify(const Problem& problem, const ProbeBank& bank,
                       const SparseMatrix& reference_stiffness, const std::vector<double>& model,
                       const SparseMatrix& baseline) {
  Generalization g;
  g.probes = static_cast<int>(bank.probes.size());
  g.supports = static_cast<int>(bank.supports.size());
  std::vector<bool> judged(bank.probes.size()), held(bank.probes.size());
  for (std::size_t p = 0; p < bank.probes.size(); ++p) {
    const Probe& probe = bank.probes[p];
    g.fitted += probe.role == ProbeRole::kFit;
    g.choosing += probe.role == ProbeRole::kSelect;
    g.held_out += probe.role == ProbeRole::kHeldOut;
    held[p] = probe.role == ProbeRole::kHeldOut;
    judged[p] = held[p] || probe.family == ProbeFamily::kNamed;
  }
  const SparseMatrix k_model = SpringRestStiffness(problem, model);
  const std::vector<double> model_errors = ProbeErrorsFor(bank, k_model, judged);
  const std::vector<double> baseline_errors = ProbeErrorsFor(bank, baseline, judged);
  g.model = SummarizeByFamily(bank, model_errors);
  g.baseline = SummarizeByFamily(bank, baseline_errors);
  const auto held_only = [&](const std::vector<double>& errors) {
    std::vector<double> mine;
    for (std::size_t p = 0; p < errors.size(); ++p)
      if (held[p]) mine.push_back(errors[p]);
    return Summarize(mine);
  };
  g.model_held_out = held_only(model_errors);
  g.baseline_held_out = held_only(baseline_errors);
  bool first = true;
  for (const Support& support : bank.supports) {
    if (!support.user) continue;
    Generalization::SupportPencil pencil;
    pencil.support = support.description;
    pencil.model = GeneralizedEigenvalueExtremes(k_model, reference_stiffness, support.constrained,
                                                 problem.dimension());
    pencil.baseline = GeneralizedEigenvalueExtremes(baseline, reference_stiffness,
                                                    support.constrained, problem.dimension());
    g.lambda_min =
        first ? pencil.model.lambda_min : std::min(g.lambda_min, pencil.model.lambda_min);
    g.lambda_max =
        first ? pencil.model.lambda_max : std::max(g.lambda_max, pencil.model.lambda_max);
    first = false;
    g.pencils.push_back(std::move(pencil));
  }
  g.bound = PencilExtremes{g.lambda_min, g.lambda_max}.Bound();
  return g;
}

}  // namespace springfit::response
