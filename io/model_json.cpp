// springfit's own model format (proto/MODEL.md): the model alone, without the run.
#include <nlohmann/json.hpp>

#include "io/model_writers.h"

namespace springfit::io {

std::string ModelJsonText(const SpringModel& model) {
  using Json = nlohmann::ordered_json;
  Json j;
  j["format"] = "springfit-model";
  j["version"] = 1;
  j["name"] = model.name;
  j["description"] = model.description;
  if (model.units) {
    j["units"] = {{"length", model.units->length},
                  {"force", model.units->force},
                  {"stiffness", model.units->stiffness},
                  {"modulus", model.units->modulus}};
  } else {
    j["units"] = nullptr;
  }
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
                       {"identified", s.identified}});
  }
  j["springs"] = std::move(springs);
  return j.dump(1) + "\n";
}

}  // namespace springfit::io
