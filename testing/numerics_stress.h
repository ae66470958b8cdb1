// Seeded extreme scenes and independent checks of springfit's numerical verdicts on them: the
// stress test of tests/engine/linalg/numerics_stress_test.cpp (a bounded number in CI) and of
// bench/numerics_stress.cpp (10,000 and more, counts in bench/RESULTS.md).
//
// A scene is drawn from the seed alone: 2D and 3D grids, jittered grids, nodes nearly on a
// line (lateral jitter down to 1e-9 of the spacing), strips of cells down to 1e-7 thick;
// per-spring stiffness spread up to 1e12; forces from 1e-9 of k h up, prescribed
// displacements up to threefold stretch; every length scaled by 1e-6 to 1e6. The checks do
// not trust the code they check: mechanism verdicts against a dense SVD of the rigidity
// matrix, equilibria against forces summed here, the normalised error against a rescaled copy
// of the scene, and every result's reported error against its model evaluated afresh.
#pragma once

#include <cstdint>
#include <string>

#include "engine/api/scene.h"

namespace springfit::examples {

Scene MakeStressScene(std::uint64_t seed);

struct StressOutcome {
  std::string kind;      // the scene's kind ("line3d", "grid2d", ...)
  bool refused = false;  // the scene was refused with an InputError (a verdict, not a failure)
  std::string refusal;   // its message
  // Failures: each names a way of being wrong that the checks can see.
  bool non_finite = false;       // NaN or Inf in an evaluation or a result
  bool false_mechanism = false;  // a mode count outside what the SVD allows
  bool inconsistent = false;     // mechanism flag, mode count and penalty disagree
  bool unbalanced = false;       // a converged equilibrium whose forces do not balance
  bool scale_dependent = false;  // the normalised error changed with the unit of length
  bool silent_wrong = false;     // an unusable result without a stop reason saying so, or a
                                 // reported error its model does not have
  bool hang = false;             // the run took longer than its bound
  int svd_checks = 0;            // topologies whose verdict was checked by SVD
  double seconds = 0.0;
  std::string detail;  // what failed, for the report

  bool failed() const {
    return non_finite || false_mechanism || inconsistent || unbalanced || scale_dependent ||
           silent_wrong || hang;
  }
};

// Builds the scene of `seed`, checks verdicts and equilibria on a few random topologies, and
// runs strategy direct with `max_seconds` as its time limit (a run past max_seconds + 2 s is a
// hang).
StressOutcome RunStressScene(std::uint64_t seed, double max_seconds);

}  // namespace springfit::examples
