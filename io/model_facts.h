// What a simulator needs to know of an exported model beyond its springs (proto/MODEL.md,
// "Simulator facts"): the stiffness spread and the dead springs, the node masses, and the
// largest stable explicit time step. The steps of ModelOfResult (spring_model.h) that set them.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "engine/api/scene.h"
#include "io/spring_model.h"

namespace springfit::io {

// The smallest, median and largest of `stiffness` (all 0 for none).
struct StiffnessSpread {
  double min = 0.0, median = 0.0, max = 0.0;
  int count = 0;
  // How many are below `fraction` x the median (the dead springs of ModelOptions).
  int below(const std::vector<double>& stiffness, double fraction) const;
};
StiffnessSpread SpreadOf(std::vector<double> stiffness);

// Flags the springs below options.dead_fraction x the result's springs' median (or drops them
// with drop_dead) and sets the stiffness facts.
void MarkDeadSprings(SpringModel& model, const ModelOptions& options);

// model.mass from options.node_mass, options.density or the materials' densities lumped on
// the FEM mesh (each element's mass in equal shares to its nodes); none when nothing gives a
// density. Throws InputError for a density without a mesh, or materials of which only some
// state a density.
void LumpMasses(SpringModel& model, const Scene& scene, const ModelOptions& options);

std::optional<double> TotalMass(const SpringModel& model);

// How the model was judged, in words every export says (the export's line, the SOFA scene's
// comment): with a linear response, fitted in the small-load limit and judged there and as the
// simulator runs it; with a nonlinear one, fitted and judged with the spring law.
std::string JudgedText(const SpringModel& model);

// 2 / omega_max for the model's springs linearised at rest and its masses, with omega_max^2
// bounded from above by the block Gershgorin bound of M^-1/2 K M^-1/2: for node i,
// (sum_s k_s) / m_i + sum_s k_s / sqrt(m_i m_j) over its springs s = (i, j) (each spring's
// block k n n^T has norm k). So the step returned is stable (undamped symplectic Euler or
// central differences); the exact limit is at most about twice it. nullopt without masses or
// springs, or when a node that a spring holds has no mass.
std::optional<double> StableExplicitTimeStep(const SpringModel& model);

}  // namespace springfit::io
