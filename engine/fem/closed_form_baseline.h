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

#include <optional>
#include <string>
#include <vector>

#include "engine/interruption.h"
#include "engine/problem.h"

namespace springfit::fem {

struct ClosedFormModel {
  std::vector<NodePair> springs;  // the mesh's edges, ascending
  std::vector<double> stiffness;  // parallel to springs
};

// Precondition: the scene's reference is an FEM model (validated).
ClosedFormModel VanGelderModel(const Scene& scene);

// The closed-form model as weights over the problem's genes: each mesh edge's stiffness on its
// gene, 0 on the other genes. nullopt when some mesh edge that a load case can see is not a
// candidate (the baseline is then not a model of the candidate set). Precondition as above.
std::optional<std::vector<double>> BaselineGeneWeights(const Problem& problem);

struct BaselineReport {
  std::string recipe = "van_gelder_1998";
  int springs = 0;
  // The baseline model's equilibria against the reference's, over the free nodes of every
  // load case (as the cost, engine/cost.h): e = sum |u_mss - u_ref|^2 / sum |u_ref|^2 and the
  // relative RMS nodal error E = sqrt(e). Only meaningful when `converged`.
  double normalized_error = 0.0;
  double rms_error = 0.0;
  bool converged = true;  // false: the baseline has no equilibrium under some load case
};

// nullopt unless the reference is an FEM model. Throws Interrupted when `interruption` stops
// it (checked inside its solves).
std::optional<BaselineReport> EvaluateClosedFormBaseline(const Problem& problem,
                                                         Interruption* interruption = nullptr);

}  // namespace springfit::fem
