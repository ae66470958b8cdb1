// The closed-form mass-spring model of an FEM reference's mesh: the baseline every
// identification on an FEM reference is measured against.
//
// van Gelder, "Approximate simulation of elastic membranes by triangulated spring meshes",
// Journal of Graphics Tools 3(2), 1998: one spring per mesh edge, of stiffness
//   2D:  k_ij = sum over the triangles T sharing edge ij of  E_T t area(T) / |l_ij|^2
//   3D:  k_ij = sum over the tetrahedra T sharing edge ij of  E_T volume(T) / |l_ij|^2
// (the 3D form is the same recipe with volumes, as used since; E_T the element's Young's
// modulus, t the thickness). It ignores Poisson's ratio, which is why identification can do
// better.
#pragma once

#include <vector>

#include "engine/api/scene.h"

namespace springfit::fem {

struct ClosedFormModel {
  std::vector<NodePair> springs;  // the mesh's edges, ascending
  std::vector<double> stiffness;  // parallel to springs
};

// Precondition: the scene's reference is an FEM model (validated).
ClosedFormModel VanGelderModel(const Scene& scene);

}  // namespace springfit::fem
