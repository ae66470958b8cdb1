#include "engine/api/mesh_facts.h"

#include "engine/fem/fem_model.h"

namespace springfit::fem {

MeshFacts MeshFactsOf(const Scene& scene) {
  const FemModel model = FemModel::Build(scene);
  MeshFacts facts;
  if (model.dimension() == 2) {
    for (const auto& e : model.elements2()) facts.element_measures.push_back(e.volume);
  } else {
    for (const auto& e : model.elements3()) facts.element_measures.push_back(e.volume);
  }
  facts.volume = model.Volume();
  const auto [quality, worst] = model.WorstQuality();
  facts.worst_quality = quality;
  facts.worst_element = worst;
  return facts;
}

}  // namespace springfit::fem
