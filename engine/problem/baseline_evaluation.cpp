#include "engine/problem/baseline_evaluation.h"

#include <algorithm>
#include <cmath>

#include "engine/fem/closed_form_baseline.h"
#include "engine/model/equilibrium.h"

namespace springfit {

using fem::ClosedFormModel;
using fem::VanGelderModel;

std::optional<std::vector<double>> BaselineGeneWeights(const Problem& problem) {
  const ClosedFormModel model = VanGelderModel(problem.scene());
  const std::vector<int>& genes = problem.gene_candidates();  // ascending
  std::vector<double> w(genes.size(), 0.0);
  for (std::size_t m = 0; m < model.springs.size(); ++m) {
    const int c = problem.CandidateIndex(model.springs[m]);
    if (c < 0) return std::nullopt;
    const auto it = std::lower_bound(genes.begin(), genes.end(), c);
    if (it == genes.end() || *it != c) continue;  // no load case sees it: no gene
    w[static_cast<std::size_t>(it - genes.begin())] = model.stiffness[m];
  }
  return w;
}

std::optional<BaselineReport> EvaluateClosedFormBaseline(const Problem& problem,
                                                         Interruption* interruption) {
  const Scene& s = problem.scene();
  if (s.reference.kind != Reference::Kind::kFem) return std::nullopt;
  const ClosedFormModel model = VanGelderModel(s);
  const int d = s.dimension;
  const SpringGeometry geometry(d, s.rest, model.springs);
  ActiveSprings springs;
  for (int m = 0; m < geometry.size(); ++m) {
    springs.index.push_back(m);
    springs.stiffness.push_back(model.stiffness[m]);
  }
  std::vector<EquilibriumSolver> solvers;
  for (const FreeNodes& free : problem.free_sets()) {
    solvers.emplace_back(geometry, free, problem.solver_options());
    solvers.back().set_interruption(interruption);
  }
  BaselineReport report;
  report.springs = geometry.size();
  double cost = 0.0;
  for (const PreparedLoadCase& lc : problem.load_cases()) {
    EquilibriumSolver& solver = solvers[lc.free_set];
    if (solver.RestMechanismModes(springs) > 0) {
      report.converged = false;
      break;
    }
    Vector u = Vector::Zero(d * s.node_count());
    if (!solver.Solve(springs, lc.force, lc.prescribed, u).converged()) {
      ThrowIfInterrupted(interruption);  // stopped, rather than without equilibrium
      report.converged = false;
      break;
    }
    const FreeNodes& free = problem.free_sets()[lc.free_set];
    for (int i = 0; i < s.node_count(); ++i) {
      if (free.free_index[i] >= 0)
        cost += (u.segment(d * i, d) - lc.reference.segment(d * i, d)).squaredNorm();
    }
  }
  if (report.converged) {
    report.normalized_error = cost / problem.reference_norm2();
    report.rms_error = std::sqrt(report.normalized_error);
  }
  return report;
}

}  // namespace springfit
