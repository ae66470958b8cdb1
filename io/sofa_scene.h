// A SOFA scene that runs as it is (proto/MODEL.md, "SOFA"): the model's springs, masses, the
// supports and forces of one load case, and a solver, in the components of one SOFA release.
// Component names change between releases (read from SOFA's sources; SofaRelease has which).
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "io/spring_model.h"

namespace springfit::io {

// The SOFA releases a scene can be written for, oldest first; the newest is the default.
inline constexpr std::array<const char*, 7> kSofaReleases = {"v23.06", "v23.12", "v24.06", "v24.12",
                                                             "v25.06", "v25.12", "v26.06"};

struct SofaOptions {
  std::string release = kSofaReleases.back();  // one of kSofaReleases
  // The load case whose supports and forces the scene applies; empty: the first.
  std::string load_case;
  // false: a static solve (StaticSolver, Newton iterations, a sparse LDL^T solver) to the
  // load case's equilibrium. true: implicit Euler time steps with Rayleigh damping (needs
  // masses).
  bool dynamic = false;
  double rayleigh_stiffness = 0.1;  // dynamic: damping proportional to K (s)
  double rayleigh_mass = 0.1;       // dynamic: damping proportional to M (1/s)
  double time_step = 0.01;          // the root node's dt (s); the static solve ignores it
  std::array<double, 3> gravity = {0.0, 0.0, 0.0};  // length / s^2; needs masses when not 0
  int newton_iterations = 50;                       // static: at most, per solve
  // Throws InputError naming the option (an unknown release lists the known ones).
  void Validate() const;
};

// What one release calls each part, from SOFA's sources (proto/MODEL.md cites the files).
struct SofaComponents {
  // Up to v24.06 SpringForceField refuses implicit and static solves (its addDForce only
  // reports an error): StiffSpringForceField then. From v24.12 SpringForceField does both and
  // StiffSpringForceField is a deprecated alias.
  const char* springs;
  // FixedConstraint up to v23.12, FixedProjectiveConstraint from v24.06 (the old name an
  // alias there, gone from the C++ headers in v26.06); the partial one alike.
  const char* fixed;
  const char* partial_fixed;
  // From v25.06 StaticSolver delegates its iterations to a NewtonRaphsonSolver, and warns on
  // its own old iteration settings.
  bool newton_raphson_component;
};
SofaComponents SofaComponentsOf(const std::string& release);

// The scene text. Throws InputError for an unknown load case, a dynamic scene or gravity
// without masses, a load case that the model cannot hold (no equilibrium of its own).
std::string SofaSceneText(const SpringModel& model, const SofaOptions& options = {});

}  // namespace springfit::io
