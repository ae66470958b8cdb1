// What the search keeps of one evaluation: the numbers selection and the trace need.
#pragma once

#include "engine/cost.h"

namespace springfit {

struct Fitness {
  double cost = 0.0;              // f (cost.h), in the scene's squared length unit
  double normalized_error = 0.0;  // e = f / sum |u^R|^2, unit-free; what selection uses
  int mechanism_modes = 0;
  bool mechanism = false;
  bool converged = true;

  static Fitness From(const Evaluation& e) {
    return {e.cost, e.normalized_error, e.mechanism_modes, e.mechanism, e.converged};
  }
  friend bool operator==(const Fitness&, const Fitness&) = default;
};

}  // namespace springfit
