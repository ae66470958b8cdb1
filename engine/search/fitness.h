// What the search keeps of one evaluation: the numbers selection and the trace need.
#pragma once

#include <cmath>
#include <limits>

#include "engine/problem/cost.h"

namespace springfit {

struct Fitness {
  double cost = 0.0;              // f (engine/problem/cost.h), in the scene's squared length unit
  double normalized_error = 0.0;  // e = f / sum |u^R|^2, unit-free; what selection uses
  int mechanism_modes = 0;
  bool mechanism = false;
  bool converged = true;

  // A non-finite error (which the cost function should never produce) becomes the worst
  // finite value, so that comparisons stay a strict weak order.
  static Fitness From(const Evaluation& e) {
    if (!std::isfinite(e.normalized_error) || !std::isfinite(e.cost)) {
      return {std::numeric_limits<double>::max(), std::numeric_limits<double>::max(),
              e.mechanism_modes, e.mechanism, false};
    }
    return {e.cost, e.normalized_error, e.mechanism_modes, e.mechanism, e.converged};
  }
  friend bool operator==(const Fitness&, const Fitness&) = default;
};

}  // namespace springfit
