#include "engine/fem/closed_form_baseline.h"

#include <algorithm>
#include <map>

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

}  // namespace springfit::fem
