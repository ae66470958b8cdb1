// springfit's own model format (proto/MODEL.md): the model alone, without the run.
#include <nlohmann/json.hpp>

#include <algorithm>

#include "io/model_writers.h"
#include "proto/scene_codec.h"

namespace springfit::io {

std::string ModelJsonText(const SpringModel& model) {
  using Json = nlohmann::ordered_json;
  Json j;
  j["format"] = "springfit-model";
  j["version"] = 1;
  j["name"] = model.name;
  j["description"] = model.description;
  j["units"] = model.units ? proto::UnitsToJson(*model.units) : proto::Json(nullptr);
  j["dimension"] = model.dimension;
  Json nodes = Json::array();
  for (int p = 0; p < model.node_count(); ++p) {
    Json x = Json::array();
    for (int c = 0; c < model.dimension; ++c) x.push_back(model.rest[model.dimension * p + c]);
    nodes.push_back(std::move(x));
  }
  j["nodes"] = std::move(nodes);
  Json springs = Json::array();
  for (const auto& s : model.springs) {
    springs.push_back({{"nodes", {s.a, s.b}},
                       {"stiffness", s.stiffness},
                       {"rest_length", s.rest_length},
                       {"identified", s.identified == SpringModel::Identified::kNotAnalysed
                                          ? Json(nullptr)
                                          : Json(s.identified == SpringModel::Identified::kYes)},
                       {"dead", s.dead}});
  }
  j["springs"] = std::move(springs);
  j["masses"] = model.mass.empty() ? Json(nullptr) : Json(model.mass);
  j["mass_source"] = model.mass_source;
  const auto& f = model.facts;
  j["facts"] = {
      {"min_stiffness", f.min_stiffness},
      {"median_stiffness", f.median_stiffness},
      {"max_stiffness", f.max_stiffness},
      {"fitted_median_stiffness", f.fitted_median_stiffness},
      {"dead_threshold", f.dead_threshold},
      {"dead_springs", f.dead},
      {"dead_dropped", f.dead_dropped},
      {"total_mass", f.total_mass ? Json(*f.total_mass) : Json(nullptr)},
      {"stable_time_step", f.stable_time_step ? Json(*f.stable_time_step) : Json(nullptr)}};
  j["response"] = model.response;
  j["elements"] = model.elements;
  j["node_sets"] = model.node_sets;
  j["node_tags"] = model.node_tags.empty() ? Json(nullptr) : Json(model.node_tags);
  // Per load case: what a simulator applies and the two equilibria to compare, per node.
  const int d = model.dimension;
  const auto per_node = [&](const std::vector<double>& flat) {
    if (flat.empty()) return Json(nullptr);
    Json rows = Json::array();
    for (int p = 0; p < model.node_count(); ++p)
      rows.push_back(std::vector<double>(flat.begin() + d * p, flat.begin() + d * (p + 1)));
    return rows;
  };
  Json cases = Json::array();
  for (const auto& lc : model.load_cases) {
    Json forces = Json::array();
    for (int p = 0; p < model.node_count(); ++p) {
      const std::vector<double> force(lc.force.begin() + d * p, lc.force.begin() + d * (p + 1));
      if (std::any_of(force.begin(), force.end(), [](double x) { return x != 0.0; }))
        forces.push_back({{"node", p}, {"force", force}});
    }
    cases.push_back({{"name", lc.name},
                     {"held", lc.held},
                     {"start", per_node(lc.start)},
                     {"forces", std::move(forces)},
                     {"reference_displacement", per_node(lc.reference_displacement)},
                     {"model_displacement", per_node(lc.model_displacement)}});
  }
  j["load_cases"] = std::move(cases);
  return j.dump(1) + "\n";
}

}  // namespace springfit::io
