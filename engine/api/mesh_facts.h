// What `check` and the exports show of an FEM reference's mesh, apart from the element
// machinery that computes it (fem_model.h): each element's rest measure, the total, and the
// worst element's shape quality.
#pragma once

#include <vector>

#include "engine/api/scene.h"

namespace springfit::fem {

struct MeshFacts {
  // Per element of scene.reference.fem, its rest measure: area x thickness (2D) or volume (3D).
  std::vector<double> element_measures;
  double volume = 0.0;  // their sum
  // The smallest shape quality (1 = equilateral) and its element's index.
  double worst_quality = 0.0;
  int worst_element = 0;
};

// Throws InputError as FemModel::Build does on a scene whose FEM reference it cannot build.
MeshFacts MeshFactsOf(const Scene& scene);

}  // namespace springfit::fem
