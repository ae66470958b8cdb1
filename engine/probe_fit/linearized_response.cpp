#include "engine/probe_fit/linearized_response.h"

#include <algorithm>
#include <cmath>

namespace springfit::response {

LinearizedResponse::LinearizedResponse(const ProbeObjective& objective, const GeneSprings& springs,
                                       Interruption* interruption, WorkerPool* pool)
    : SpringSensitivities(objective.scale(), springs.size(), interruption, pool),
      objective_(&objective),
      springs_(&springs) {}

bool LinearizedResponse::At(const std::vector<double>& weights) {
  const Problem& problem = objective_->problem();
  const ProbeBank& bank = objective_->bank();
  const SparseMatrix k = SpringRestStiffness(problem, weights);
  parts_.clear();
  supports_.clear();
  systems_.clear();
  std::vector<std::vector<int>> probes;
  for (std::size_t s : objective_->fitted_supports()) {
    supports_.push_back(s);
    systems_.emplace_back(problem.dimension(), bank.supports[s].constrained);
    probes.emplace_back();
    for (std::size_t p = 0; p < bank.probes.size(); ++p)
      if (objective_->weight()[p] > 0.0 && bank.probes[p].support == static_cast<int>(s))
        probes.back().push_back(static_cast<int>(p));
    Part part;
    part.key = s;
    parts_.push_back(std::move(part));
  }
  std::vector<char> held(parts_.size(), 0);
  Run([&](std::size_t i) {
    Part& part = parts_[i];
    SupportSystem& system = systems_[i];
    if (!(held[i] = system.Factorize(k))) return;
    part.columns = FreeColumns(*springs_, system);
    const auto count = static_cast<Eigen::Index>(probes[i].size());
    const int n = system.free_dofs();
    Matrix u(n, count);
    for (Eigen::Index j = 0; j < count; ++j) {
      const Probe& probe = bank.probes[static_cast<std::size_t>(probes[i][j])];
      u.col(j) = system.RightHandSide(probe.force, probe.prescribed);
    }
    SolveColumns(i, u);
    part.residual.resize(n, count);
    part.elongation.resize(springs_->size(), count);
    for (Eigen::Index j = 0; j < count; ++j) {
      const std::size_t p = static_cast<std::size_t>(probes[i][j]);
      const Probe& probe = bank.probes[p];
      const double root = std::sqrt(objective_->weight()[p]);
      const Vector full = system.Scatter(u.col(j), probe.prescribed);
      part.residual.col(j) = root * (u.col(j) - system.Gather(probe.reference));
      part.elongation.col(j) = root * Elongations(*springs_, full);
    }
  });
  return std::find(held.begin(), held.end(), 0) == held.end();
}

FactorizedOn LinearizedResponse::Factorized() const {
  return [this](std::size_t support) -> const SupportSystem* {
    for (std::size_t i = 0; i < supports_.size(); ++i)
      if (supports_[i] == support) return &systems_[i];
    return nullptr;
  };
}

void LinearizedResponse::Solve(std::size_t part, Matrix& b) const {
  systems_[part].SolveColumns(b);
}

}  // namespace springfit::response
