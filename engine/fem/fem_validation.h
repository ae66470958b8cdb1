// The semantic rules of a finite-element reference (proto/SCENE.md, "fem"), checked once at
// the boundary with the rest of the scene (ValidateScene, engine/api/scene.h).
#pragma once

#include "engine/api/scene.h"

namespace springfit::fem {

// Throws InputError naming the JSON path of the first broken rule:
// - at least one element; each with d + 1 distinct node indices in range;
// - every node belongs to some element (an FEM reference gives every node its stiffness);
// - no degenerate element (quality below 1e-8, SimplexQuality in fem_model.h); no element
//   inverted at rest (either node order is accepted, so an inverted element shows as two
//   elements on the same side of their shared edge or face: a fold); at most two elements per
//   edge (2D) or face (3D);
// - materials: young finite and > 0, poisson finite and in (-1, 0.5); regions: one material
//   index per element, in range;
// - plane and thickness only in 2D; thickness finite and > 0.
void ValidateFemReference(const Scene& scene);

}  // namespace springfit::fem
