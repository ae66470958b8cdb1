// The units of a scene (proto/SCENE.md, "Units"): a length and a force, and the stiffness and
// modulus they imply. springfit's numbers are consistent in any units; these say which, so that
// a reader (a simulator, ParaView) does not guess.
#pragma once

#include <string>

#include "engine/model/scene.h"

namespace springfit {

struct DerivedUnits {
  std::string length;     // as given
  std::string force;      // as given
  std::string stiffness;  // force / length, e.g. "mN/mm"
  std::string modulus;    // force / length^2 by its name where it has one (mN/mm^2 = kPa)
  // Time is the second wherever a simulator steps in time; the mass unit follows from
  // F = m a: force x s^2 / length, by its name where it has one (mN s^2/mm = kg, N s^2/mm = t).
  std::string time = "s";
  std::string mass;
};

// Checks `units` (throws InputError at "units.length", "units.force" or "units.modulus": an
// unknown unit, or a modulus that is not force / length^2) and derives the rest.
DerivedUnits DeriveUnits(const Scene::Units& units);

}  // namespace springfit
