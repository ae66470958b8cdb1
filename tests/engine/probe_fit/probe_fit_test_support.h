// What the probe fit's tests (engine/probe_fit/) share: the kidney at rest, its bank and
// prior.
#pragma once
#include <algorithm>
#include <string>
#include <vector>

#include "engine/probe_fit/generalization.h"
#include "engine/probe_fit/probe_bank.h"
#include "engine/probe_fit/response_fit.h"
#include "engine/problem/baseline_evaluation.h"
#include "engine/problem/rest_stiffness.h"
#include "io/example_catalog.h"

namespace springfit::response {

// The largest ratio of the model's held-out median E to the baseline's over the force families
// (point, patch, body): the loads whose pooled median the fit's claims were first stated on,
// before the tool loads (push, grasp), where the recipe comes closer, joined the held-out pool.
inline double ForceFamiliesRatio(const Generalization& g) {
  double worst = 0.0;
  for (const FamilyErrors& m : g.model) {
    if (m.family != ProbeFamily::kPoint && m.family != ProbeFamily::kPatch &&
        m.family != ProbeFamily::kBody)
      continue;
    for (const FamilyErrors& b : g.baseline)
      if (b.family == m.family) worst = std::max(worst, m.errors.median / b.errors.median);
  }
  return worst;
}

// An FEM example (the kidney unless named), its reference stiffness at rest, the default probe
// bank, and the closed-form baseline as the prior.
struct KidneyAtRest {
  explicit KidneyAtRest(const std::string& example = "fem-kidney-2d")
      : problem(examples::Make(example)) {}
  explicit KidneyAtRest(Scene scene) : problem(std::move(scene)) {}
  Problem problem;
  SparseMatrix k = ReferenceRestStiffness(problem);
  ResponseFitOptions options;
  ProbeBanks banks = MakeProbeBanks(problem, k, options.probes);
  std::vector<double> prior = *BaselineGeneWeights(problem);
  const ProbeBank& bank = banks.fit;
  // The certificate of `weights` beside `prior`'s.
  Generalization Certify(const std::vector<double>& weights) const {
    return Certifier(problem, bank, banks.held_out, k)
        .Certify(weights, SpringRestStiffness(problem, prior));
  }
};

}  // namespace springfit::response
