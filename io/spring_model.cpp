#include "io/spring_model.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <utility>

#include "engine/input_error.h"

namespace springfit::io {
namespace {

NodePair Ordered(NodePair p) {
  if (p.first > p.second) std::swap(p.first, p.second);
  return p;
}

}  // namespace

SpringModel ModelOfResult(const Problem& problem, const proto::StoredResult& result) {
  const Scene& scene = problem.scene();
  proto::ExpectResultOfScene(result, problem);
  SpringModel model;
  model.name = scene.name;
  model.dimension = scene.dimension;
  model.rest.assign(scene.rest.data(), scene.rest.data() + scene.rest.size());
  model.description = "springfit, strategy " + result.strategy;
  if (result.seed) model.description += ", seed " + std::to_string(*result.seed);
  if (result.rms_error) {
    char e[32];
    std::snprintf(e, sizeof e, ", E %.4g", *result.rms_error);
    model.description += e;
  }
  // Units, where the scene states them: in the description every format writes, and as data.
  if (scene.units) {
    model.units = DeriveUnits(*scene.units);
    model.description += "; units: length " + model.units->length + ", force " +
                         model.units->force + ", stiffness " + model.units->stiffness;
  }

  std::set<NodePair> candidates;
  for (const NodePair& p : problem.candidates().pairs) candidates.insert(Ordered(p));
  std::set<NodePair> undetermined;
  for (const NodePair& p : result.undetermined) undetermined.insert(Ordered(p));
  const auto add = [&](NodePair p, double stiffness, bool identified) {
    SpringModel::Spring s;
    s.a = p.first;
    s.b = p.second;
    s.stiffness = stiffness;
    const int d = model.dimension;
    s.rest_length =
        (scene.rest.segment(d * p.first, d) - scene.rest.segment(d * p.second, d)).norm();
    s.identified = identified;
    model.springs.push_back(s);
  };
  const double training = problem.training_stiffness();
  std::set<NodePair> present;
  for (std::size_t i = 0; i < result.springs.size(); ++i) {
    const NodePair p = Ordered(result.springs[i]);
    if (!candidates.count(p) || !present.insert(p).second) {
      throw InputError("springs[" + std::to_string(i) + "]",
                       "(" + std::to_string(p.first) + ", " + std::to_string(p.second) + ") is " +
                           (candidates.count(p) ? "listed twice" : "not a candidate of the scene"));
    }
    add(p, result.stiffness.empty() ? training : result.stiffness[i], !undetermined.count(p));
  }
  // The candidates no load case sees, with the problem's stiffness for them (Problem::
  // unidentifiable_stiffness: the closed-form model's on an FEM mesh edge): the model as the
  // certificate judged it.
  std::map<NodePair, double> unseen_stiffness;
  for (std::size_t u = 0; u < problem.unidentifiable().size(); ++u)
    unseen_stiffness[Ordered(
        problem.candidates().pairs[static_cast<std::size_t>(problem.unidentifiable()[u])])] =
        problem.unidentifiable_stiffness()[u];
  for (const NodePair& u : result.unidentifiable) {
    const NodePair p = Ordered(u);
    const auto k = unseen_stiffness.find(p);
    if (candidates.count(p) && present.insert(p).second)
      add(p, k == unseen_stiffness.end() ? training : k->second, false);
  }
  return model;
}

}  // namespace springfit::io
