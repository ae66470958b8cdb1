#include "io/spring_model.h"

#include <map>
#include <set>
#include <utility>

#include <fmt/format.h>

#include "engine/api/input_error.h"
#include "engine/api/problem.h"
#include "io/model_facts.h"

namespace springfit::io {
namespace {

// Each load case as a simulator applies it, the reference's equilibrium, and the model's own as
// a simulator computes it: with the simulator's spring law (nonlinear springs: f = k (l - L0)
// along the current direction), whatever response the fit was judged with, so that what an
// export states is what SOFA reaches (docs/ARCHITECTURE.md, "The nonlinear judgement").
void AddLoadCases(SpringModel& model, const Problem& problem) {
  const Scene& scene = problem.scene();
  const int d = model.dimension;
  ActiveSprings springs;
  for (const auto& s : model.springs) {
    springs.index.push_back(problem.CandidateIndex({s.a, s.b}));
    springs.stiffness.push_back(s.stiffness);
  }
  CostOptions every_case;
  every_case.solve_cases_of_mechanisms = true;
  every_case.response = Response::kNonlinear;
  CostFunction cost(problem, every_case);
  std::vector<Vector> displacements;
  cost.Evaluate(springs, &displacements);
  for (std::size_t k = 0; k < scene.load_cases.size(); ++k) {
    const LoadCase& lc = scene.load_cases[k];
    const PreparedLoadCase& prepared = problem.load_cases()[k];
    SpringModel::LoadCase out;
    out.name = lc.name;
    std::set<int> held(lc.fixed.begin(), lc.fixed.end());
    for (const NodalLoad& m : lc.displacements) held.insert(m.nodes.begin(), m.nodes.end());
    out.held.assign(held.begin(), held.end());
    out.start = model.rest;
    out.force.assign(prepared.force.data(), prepared.force.data() + prepared.force.size());
    for (int i = 0; i < model.node_count(); ++i) {
      for (int c = 0; c < d; ++c) {
        if (held.count(i)) {
          out.start[d * i + c] += prepared.prescribed[d * i + c];
          out.force[d * i + c] = 0.0;  // a force on a held node goes to the support
        }
      }
    }
    out.reference_displacement.assign(prepared.reference.data(),
                                      prepared.reference.data() + prepared.reference.size());
    if (k < displacements.size() && displacements[k].size() == prepared.reference.size())
      out.model_displacement.assign(displacements[k].data(),
                                    displacements[k].data() + displacements[k].size());
    model.load_cases.push_back(std::move(out));
  }
}

// The line every format writes: the strategy and seed, the scene's units where it states them,
// and the result's verdict line (as run, result and the dashboard show it; E alone for a result
// written before it had one). The units come before the verdict line, which is the longest
// part: a format that cuts the line (legacy VTK's 256-character title) keeps them.
std::string DescriptionOf(const proto::StoredResult& result, const Scene& scene) {
  std::string description = "springfit, strategy " + result.strategy;
  if (result.seed) description += ", seed " + std::to_string(*result.seed);
  if (scene.units) {
    const DerivedUnits units = DeriveUnits(*scene.units);
    description += "; units: length " + units.length + ", force " + units.force + ", stiffness " +
                   units.stiffness + ", mass " + units.mass + ", time " + units.time;
  }
  if (result.outcome) {
    description += "; " + result.outcome->Headline();
  } else if (result.rms_error) {
    description += fmt::format(", E {:.4g}", *result.rms_error);
  }
  return description;
}

// The result's springs, then the candidates no load case sees (with the problem's stiffness
// for them, Problem::unidentifiable_stiffness: the closed-form model's on an FEM mesh edge: the
// model as the certificate judged it), each with whether the load cases determine it. Throws
// InputError on a spring that is not a candidate or is listed twice.
void AddSprings(SpringModel& model, const Problem& problem, const proto::StoredResult& result) {
  const Scene& scene = problem.scene();
  // (A result's pairs are read ordered, as the problem's candidates are.)
  const auto candidate = [&](NodePair p) { return problem.CandidateIndex(p) >= 0; };
  const std::set<NodePair> undetermined(result.undetermined.begin(), result.undetermined.end());
  // Not in a group or unseen: determined, when the groups were analysed.
  const SpringModel::Identified otherwise = result.groups_analysed
                                                ? SpringModel::Identified::kYes
                                                : SpringModel::Identified::kNotAnalysed;
  if (!result.groups_analysed) model.groups_not_analysed = result.groups_not_analysed;
  const auto add = [&](NodePair p, double stiffness, SpringModel::Identified identified,
                       bool between_held) {
    SpringModel::Spring s;
    s.a = p.first;
    s.b = p.second;
    s.stiffness = stiffness;
    const int d = model.dimension;
    s.rest_length =
        (scene.rest.segment(d * p.first, d) - scene.rest.segment(d * p.second, d)).norm();
    s.identified = identified;
    s.between_held = between_held;
    model.springs.push_back(s);
  };
  const double training = problem.training_stiffness();
  std::set<NodePair> present;
  for (std::size_t i = 0; i < result.springs.size(); ++i) {
    const NodePair p = result.springs[i];
    if (!candidate(p) || !present.insert(p).second) {
      throw InputError("springs[" + std::to_string(i) + "]",
                       "(" + std::to_string(p.first) + ", " + std::to_string(p.second) + ") is " +
                           (candidate(p) ? "listed twice" : "not a candidate of the scene"));
    }
    add(p, result.stiffness.empty() ? training : result.stiffness[i],
        undetermined.count(p) ? SpringModel::Identified::kNo : otherwise, false);
  }
  std::map<NodePair, double> unseen_stiffness;
  for (std::size_t u = 0; u < problem.unidentifiable().size(); ++u)
    unseen_stiffness[problem.candidates()
                         .pairs[static_cast<std::size_t>(problem.unidentifiable()[u])]] =
        problem.unidentifiable_stiffness()[u];
  for (const NodePair& p : result.unidentifiable) {
    const auto k = unseen_stiffness.find(p);
    if (candidate(p) && present.insert(p).second)
      add(p, k == unseen_stiffness.end() ? training : k->second, SpringModel::Identified::kNo,
          true);
  }
}

}  // namespace

SpringModel ModelOfResult(const Problem& problem, const proto::StoredResult& result,
                          const ModelOptions& options) {
  options.Validate();
  const Scene& scene = problem.scene();
  proto::ExpectResultOfScene(result, problem);
  SpringModel model;
  model.name = scene.name;
  model.dimension = scene.dimension;
  model.rest.assign(scene.rest.data(), scene.rest.data() + scene.rest.size());
  model.description = DescriptionOf(result, scene);
  if (scene.units) model.units = DeriveUnits(*scene.units);
  AddSprings(model, problem, result);
  model.response = problem.response() == Response::kLinear ? "linear" : "nonlinear";
  model.node_sets = scene.node_sets;
  model.node_tags = scene.node_tags;
  if (scene.reference.kind == Reference::Kind::kFem) model.elements = scene.reference.fem.elements;
  MarkDeadSprings(model, options);
  LumpMasses(model, scene, options);
  AddLoadCases(model, problem);
  model.facts.total_mass = TotalMass(model);
  model.facts.stable_time_step = StableExplicitTimeStep(model);
  return model;
}

}  // namespace springfit::io
