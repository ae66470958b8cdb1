#include "engine/fem/closed_form_baseline.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "engine/equilibrium.h"
#include "engine/fem/fem_model.h"

namespace springfit::fem {

ClosedFormModel VanGelderModel(const Scene& scene) {
  const FemModel model = FemModel::Build(scene);
  const FemReference& fem = scene.reference.fem;
  const int d = scene.dimension;
  std::map<NodePair, double> stiffness;
  for (std::size_t e = 0; e < fem.elements.size(); ++e) {
    const std::vector<int>& el = fem.elements[e];
    // The element's rest measure (2D: area x thickness), as the model computed it.
    const double measure = d == 2 ? model.elements2()[e].volume : model.elements3()[e].volume;
    const double young = fem.MaterialOf(e).young;
    for (int a = 0; a <= d; ++a) {
      for (int b = a + 1; b <= d; ++b) {
        const NodePair edge{std::min(el[a], el[b]), std::max(el[a], el[b])};
        const double length2 =
            (scene.rest.segment(d * edge.first, d) - scene.rest.segment(d * edge.second, d))
                .squaredNorm();
        stiffness[edge] += young * measure / length2;
      }
    }
  }
  ClosedFormModel out;
  for (const auto& [edge, k] : stiffness) {
    out.springs.push_back(edge);
    out.stiffness.push_back(k);
  }
  return out;
}

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

}  // namespace springfit::fem
