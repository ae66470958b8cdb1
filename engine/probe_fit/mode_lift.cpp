#include "engine/probe_fit/mode_lift.h"

#include "engine/probe_fit/gene_springs.h"
#include "engine/probe_fit/mode_cuts.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/probe_fit/quadratic_nnls.h"
#include "engine/problem/rest_stiffness.h"
#include "engine/runtime/options_check.h"

namespace springfit::response {

void ModeLiftOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  check.Require(target > 0.0 && std::isfinite(target), "target", target, "value > 0");
  check.Require(rounds >= 1, "rounds", rounds, "value >= 1");
  check.Require(modes_per_support >= 1, "modes_per_support", modes_per_support, "value >= 1");
}

ModeLift LiftSoftModes(const Problem& problem, const std::vector<double>& weights,
                       const Vector& scale,
                       const std::vector<std::pair<int, SupportSystem>>& references,
                       const ModeLiftOptions& options, Interruption* interruption) {
  options.Validate();
  const GeneSprings springs = GeneSpringsOf(problem);
  ModeLift lift{weights, 0, 0};
  for (int round = 0; round < options.rounds; ++round) {
    ThrowIfInterrupted(interruption);
    const SparseMatrix model = SpringRestStiffness(problem, lift.weights);
    // Per soft mode j: its eigenvalue and a_j, the eigenvalue's derivative in each stiffness.
    std::vector<double> lambdas;
    std::vector<Vector> slopes;
    for (const auto& [support, reference] : references) {
      for (const SoftMode& mode :
           SoftModes(model, reference, options.target, options.modes_per_support,
                     kLanczosIterations, interruption)) {
        Vector slope = ModeSlope(springs, mode, reference);
        for (std::size_t g = 0; g < lift.weights.size(); ++g)
          if (!(lift.weights[g] > 0.0)) slope[static_cast<Eigen::Index>(g)] = 0.0;  // absent
        lambdas.push_back(mode.lambda);
        slopes.push_back(std::move(slope));
      }
    }
    if (lambdas.empty()) break;
    // The dual: minimise 1/2 mu^T (A S^2 A^T) mu - (target - lambda)^T mu over mu >= 0.
    const auto modes = static_cast<Eigen::Index>(lambdas.size());
    const Vector s2 = scale.cwiseAbs2();
    Matrix h(modes, modes);
    Vector c(modes);
    for (Eigen::Index i = 0; i < modes; ++i) {
      c[i] = options.target - lambdas[static_cast<std::size_t>(i)];
      for (Eigen::Index j = 0; j <= i; ++j)
        h(i, j) = h(j, i) = slopes[static_cast<std::size_t>(i)].cwiseProduct(s2).dot(
            slopes[static_cast<std::size_t>(j)]);
    }
    const Vector mu = SolveQuadraticNnls(h, c, Vector(), {}, {}, interruption).x;
    Vector change = Vector::Zero(scale.size());
    for (Eigen::Index j = 0; j < modes; ++j)
      change += mu[j] * slopes[static_cast<std::size_t>(j)].cwiseProduct(s2);
    for (std::size_t g = 0; g < lift.weights.size(); ++g)
      lift.weights[g] += change[static_cast<Eigen::Index>(g)];
    ++lift.rounds;
    lift.modes += static_cast<int>(modes);
  }
  return lift;
}

}  // namespace springfit::response
