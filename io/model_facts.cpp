#include "io/model_facts.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <fmt/format.h>

#include "engine/api/analysis.h"
#include "engine/api/input_error.h"

namespace springfit::io {

void ModelOptions::Validate() const {
  if (density && !(std::isfinite(*density) && *density > 0.0))
    throw InputError("--density", "must be a finite number > 0");
  if (node_mass && !(std::isfinite(*node_mass) && *node_mass > 0.0))
    throw InputError("--node-mass", "must be a finite number > 0");
  if (density && node_mass)
    throw InputError("--node-mass", "give --density (lumped on the mesh) or --node-mass, not both");
  if (!(dead_fraction >= 0.0 && dead_fraction < 1.0))
    throw InputError("--dead-fraction", "must be in [0, 1)");
}

StiffnessSpread SpreadOf(std::vector<double> stiffness) {
  StiffnessSpread s;
  s.count = static_cast<int>(stiffness.size());
  if (stiffness.empty()) return s;
  std::sort(stiffness.begin(), stiffness.end());
  s.min = stiffness.front();
  s.max = stiffness.back();
  const std::size_t n = stiffness.size();
  s.median = n % 2 ? stiffness[n / 2] : 0.5 * (stiffness[n / 2 - 1] + stiffness[n / 2]);
  return s;
}

int StiffnessSpread::below(const std::vector<double>& stiffness, double fraction) const {
  const double threshold = fraction * median;
  return static_cast<int>(
      std::count_if(stiffness.begin(), stiffness.end(), [&](double k) { return k < threshold; }));
}

void MarkDeadSprings(SpringModel& model, const ModelOptions& options) {
  // The threshold is the result's springs' median, as `run` and `result` print it: the springs
  // between held nodes that the export adds are not the fit's (a model of only those: theirs).
  std::vector<double> fitted, all;
  for (const auto& s : model.springs) {
    all.push_back(s.stiffness);
    if (!s.between_held) fitted.push_back(s.stiffness);
  }
  auto& facts = model.facts;
  facts.fitted_median_stiffness = SpreadOf(fitted.empty() ? all : fitted).median;
  facts.dead_fraction = options.dead_fraction;
  facts.dead_threshold = options.dead_fraction * facts.fitted_median_stiffness;
  facts.dead_dropped = options.drop_dead;
  for (auto& s : model.springs) {
    s.dead = s.stiffness < facts.dead_threshold;
    facts.dead += s.dead ? 1 : 0;
  }
  if (options.drop_dead)
    std::erase_if(model.springs, [](const SpringModel::Spring& s) { return s.dead; });
  // The stiffness the file holds (with drop_dead, the kept springs').
  std::vector<double> held;
  for (const auto& s : model.springs) held.push_back(s.stiffness);
  const StiffnessSpread spread = SpreadOf(held);
  facts.min_stiffness = spread.min;
  facts.median_stiffness = spread.median;
  facts.max_stiffness = spread.max;
}

void LumpMasses(SpringModel& model, const Scene& scene, const ModelOptions& options) {
  const int n = model.node_count();
  if (options.node_mass) {
    model.mass.assign(static_cast<std::size_t>(n), *options.node_mass);
    model.mass_source = fmt::format("node mass {:.6g} (--node-mass)", *options.node_mass);
    return;
  }
  const bool fem = scene.reference.kind == Reference::Kind::kFem;
  if (options.density && !fem) {
    throw InputError("--density",
                     "the scene has no FEM mesh to lump a density on: give --node-mass, every "
                     "node's mass");
  }
  if (!fem) return;
  const FemReference& mesh = scene.reference.fem;
  if (!options.density) {
    // The materials' densities: all or none.
    std::size_t with = 0;
    for (const Material& m : mesh.materials) with += m.density ? 1 : 0;
    if (with == 0) return;
    if (with != mesh.materials.size()) {
      for (std::size_t i = 0; i < mesh.materials.size(); ++i) {
        if (!mesh.materials[i].density)
          throw InputError("reference.materials[" + std::to_string(i) + "].density",
                           "missing, where other materials state theirs: give it, or --density "
                           "for every element");
      }
    }
  }
  const int d = model.dimension;
  // Each element's rest measure (2D: area x thickness) as the FEM model computes it.
  const fem::MeshFacts facts = fem::MeshFactsOf(scene);
  model.mass.assign(static_cast<std::size_t>(n), 0.0);
  for (std::size_t e = 0; e < mesh.elements.size(); ++e) {
    const std::vector<int>& nodes = mesh.elements[e];
    const double measure = facts.element_measures[e];
    const double rho = options.density ? *options.density : *mesh.MaterialOf(e).density;
    for (int node : nodes) model.mass[node] += rho * measure / static_cast<double>(nodes.size());
  }
  if (options.density) {
    model.mass_source = fmt::format("density {:.6g} (--density)", *options.density);
  } else {
    model.mass_source = "the materials' density";
  }
  model.mass_source += " lumped on the " + std::to_string(mesh.elements.size()) +
                       (d == 2 ? " triangles" : " tetrahedra");
}

std::optional<double> TotalMass(const SpringModel& model) {
  if (model.mass.empty()) return std::nullopt;
  double total = 0.0;
  for (double m : model.mass) total += m;
  return total;
}

std::optional<double> StableExplicitTimeStep(const SpringModel& model) {
  if (model.mass.empty() || model.springs.empty()) return std::nullopt;
  const std::size_t n = model.mass.size();
  std::vector<double> diagonal(n, 0.0), coupling(n, 0.0);
  for (const auto& s : model.springs) {
    const double ma = model.mass[static_cast<std::size_t>(s.a)];
    const double mb = model.mass[static_cast<std::size_t>(s.b)];
    if (!(ma > 0.0) || !(mb > 0.0)) return std::nullopt;
    diagonal[static_cast<std::size_t>(s.a)] += s.stiffness;
    diagonal[static_cast<std::size_t>(s.b)] += s.stiffness;
    const double off = s.stiffness / std::sqrt(ma * mb);
    coupling[static_cast<std::size_t>(s.a)] += off;
    coupling[static_cast<std::size_t>(s.b)] += off;
  }
  double omega2 = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (diagonal[i] > 0.0) omega2 = std::max(omega2, diagonal[i] / model.mass[i] + coupling[i]);
  }
  if (!(omega2 > 0.0)) return std::nullopt;
  return 2.0 / std::sqrt(omega2);
}

std::string JudgedText(const SpringModel& model) {
  if (model.response == "linear")
    return "judged: E as simulated and the amplitudes with nonlinear springs (as a simulator runs "
           "them) at the loads' own size; E small-load, the held-out probes and the eigenvalues in "
           "the small-load limit the fit used (rest-linear springs)";
  return "judged: E and the amplitudes with nonlinear springs (as a simulator runs them) at the "
         "loads' own size; the held-out probes and the eigenvalues, where given, in the small-load "
         "limit (rest-linear springs)";
}

}  // namespace springfit::io
