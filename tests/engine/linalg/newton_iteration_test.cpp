// The Newton iteration both equilibrium solvers share (engine/linalg/newton_iteration.h), on
// one-dimensional energies whose minimiser is known.
#include "engine/linalg/newton_iteration.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace springfit {
namespace {

// E(x) = x^4 / 4 - f x (minimum at x = cbrt(f)), with a Newton direction from E'' that can be
// replaced by an uphill one, a stop once the current point's |E'| is below `tolerance` or after
// `limit` steps, and an acceptance that can refuse the point (as the FEM's does a non-finite
// energy).
struct QuarticSteps {
  double f = 8.0;
  double x = 1.0;
  double trial_x = 1.0;
  double direction = 0.0;
  double tolerance = 1e-12;
  int limit = 50;
  bool uphill = false;
  bool refuse = false;
  int rejects = 0;
  bool converged = false;

  double Gradient(double at) const { return at * at * at - f; }
  EnergyPoint Point(double at) const {
    return {at * at * at * at / 4.0 - f * at, std::abs(at * at * at * at / 4.0) + std::abs(f * at),
            std::abs(Gradient(at))};
  }
  const char* StopBeforeStep(int iterations, const EnergyPoint& at) {
    if (at.residual <= tolerance) {
      converged = true;
      return "";
    }
    if (iterations >= limit) return "limit";
    return nullptr;
  }
  const char* Direction(double& slope) {
    direction = -Gradient(x) / (3.0 * x * x);
    if (uphill) direction = -direction;
    slope = Gradient(x) * direction;
    return nullptr;
  }
  EnergyPoint Trial(double alpha) {
    trial_x = x + alpha * direction;
    return Point(trial_x);
  }
  const char* Accept(EnergyPoint&) {
    if (refuse) return "refused";
    x = trial_x;
    return nullptr;
  }
  void Reject() { ++rejects; }
};

TEST(NewtonIteration, ConvergesQuadraticallyAndCountsItsSteps) {
  QuarticSteps steps;
  EnergyPoint at = steps.Point(steps.x);
  int iterations = 0, rejected = 0;
  const std::string why =
      NewtonIterate(steps, at, LineSearchOptions{1e-4, 30}, iterations, &rejected);
  EXPECT_EQ(why, "");
  EXPECT_TRUE(steps.converged);
  EXPECT_NEAR(steps.x, 2.0, 1e-12);
  EXPECT_GT(iterations, 2);
  EXPECT_LT(iterations, 15);  // Newton: a handful of steps from x = 1 (a full search would be more)
  EXPECT_EQ(at.energy, steps.Point(steps.x).energy);  // `at` follows the accepted point
  EXPECT_EQ(steps.rejects, 0);
}

TEST(NewtonIteration, StopTestsComeBeforeTheStep) {
  QuarticSteps steps;
  steps.limit = 2;
  EnergyPoint at = steps.Point(steps.x);
  int iterations = 0;
  EXPECT_EQ(std::string(NewtonIterate(steps, at, LineSearchOptions{1e-4, 30}, iterations)),
            "limit");
  EXPECT_EQ(iterations, 2);
  // Already at the minimum: no step is taken, whatever the limit.
  QuarticSteps there;
  there.x = 2.0;
  there.limit = 0;
  EnergyPoint at_minimum = there.Point(there.x);
  iterations = 0;
  EXPECT_EQ(std::string(NewtonIterate(there, at_minimum, LineSearchOptions{1e-4, 30}, iterations)),
            "");
  EXPECT_TRUE(there.converged);
  EXPECT_EQ(iterations, 0);
}

TEST(NewtonIteration, ARefusedPointEndsTheIterationWithItsReason) {
  QuarticSteps steps;
  steps.refuse = true;
  EnergyPoint at = steps.Point(steps.x);
  int iterations = 0;
  EXPECT_EQ(std::string(NewtonIterate(steps, at, LineSearchOptions{1e-4, 30}, iterations)),
            "refused");
  EXPECT_EQ(iterations, 1);
  // `at` already holds the line search's point when the solver is asked to accept it.
  EXPECT_EQ(at.energy, steps.Point(steps.trial_x).energy);
  EXPECT_NE(steps.trial_x, 1.0);
}

TEST(NewtonIteration, AnUphillDirectionFindsNoDecreaseAndIsRejected) {
  QuarticSteps steps;
  steps.uphill = true;
  EnergyPoint at = steps.Point(steps.x);
  int iterations = 0, rejected = 0;
  const std::string why =
      NewtonIterate(steps, at, LineSearchOptions{1e-4, 5}, iterations, &rejected);
  EXPECT_EQ(why, "the line search found no decrease of the energy (round-off)");
  EXPECT_EQ(iterations, 1);
  EXPECT_EQ(rejected, 5);
  EXPECT_EQ(steps.rejects, 1);
  EXPECT_EQ(steps.x, 1.0);  // the point is kept
}

}  // namespace
}  // namespace springfit
