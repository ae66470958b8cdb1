// A spring model's response to the fitted probes linearised at rest: the probe fit's objective
// (spring_sensitivities.h) with H the model's rest stiffness on each support, G the springs'
// rest directions and s_p = G^T u_p the stretches' linearisation (dK u = G diag(s) dk). One
// factorisation per support serves all its probes, batched as many right-hand sides.
#pragma once

#include <vector>

#include "engine/probe_fit/probe_objective.h"
#include "engine/probe_fit/spring_sensitivities.h"

namespace springfit::response {

class LinearizedResponse : public SpringSensitivities {
 public:
  // `objective` and `springs` (GeneSpringsOf its problem) must outlive this object.
  LinearizedResponse(const ProbeObjective& objective, const GeneSprings& springs,
                     Interruption* interruption = nullptr, WorkerPool* pool = nullptr);

  // The model factorised on every fitted support and solved for every fitted probe; false when
  // some fitted support does not hold it (a mechanism).
  bool At(const std::vector<double>& weights) override;
  // The model of the last successful At() factorised on every fitted support (null on
  // others), for the judgements of that model (ProbeObjective::SelectError, LambdaMin).
  FactorizedOn Factorized() const override;

 private:
  void Solve(std::size_t part, Matrix& b) const override;

  const ProbeObjective* objective_;
  const GeneSprings* springs_;
  std::vector<std::size_t> supports_;   // per part
  std::vector<SupportSystem> systems_;  // per part
};

}  // namespace springfit::response
