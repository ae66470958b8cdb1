// The damped Newton iteration of both equilibrium solvers (the MSS's, engine/model/equilibrium.h,
// and the FEM reference's, engine/fem/fem_equilibrium.h), in one place: the loop of named steps
// (NewtonIterate) and its backtracking line search, where the step is halved from its full
// length until the energy decreases enough (Armijo's condition) and the energy's round-off is
// judged the same way in both. What differs between the solvers (their stop tests, how they
// factorise, what a point holds) is each one's `Steps`.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

namespace springfit {

// A point of the search: the energy, the magnitude of its terms (its round-off scale) and the
// gradient's largest entry (the line search reads it under RoundoffRule::kGradientDecides; the
// solvers' stop tests read it too).
struct EnergyPoint {
  double energy = 0.0;
  double magnitude = 0.0;
  double residual = 0.0;
};

// An energy is known to 64 ulps of the larger magnitude of its terms (a sum of many terms
// cancels): a difference below it is round-off.
inline double EnergyRoundoff(double magnitude, double trial_magnitude) {
  constexpr double kEnergyRoundoffUlps = 64.0;
  return kEnergyRoundoffUlps * std::numeric_limits<double>::epsilon() *
         std::max(magnitude, trial_magnitude);
}

// What counts as progress when the energy's change is within its round-off.
enum class RoundoffRule {
  // A trial whose gradient is smaller (the MSS solver: it assembles the gradient with every
  // trial, and near equilibrium E is flat to round-off while the gradient still tells).
  kGradientDecides,
  // Any trial: the decrease is asked for up to the round-off (the FEM solver, which assembles
  // the energy alone per trial).
  kSlack,
};

struct LineSearchOptions {
  double armijo = 1e-4;  // the sufficient decrease's fraction of the slope
  int trials = 1;        // step lengths tried: 1, 1/2, 1/4, ...
  RoundoffRule rule = RoundoffRule::kSlack;
};

// `trial(alpha)` evaluates the point at step length alpha and returns it. Returns the accepted
// point (the last one `trial` evaluated), or nothing when no step length was accepted;
// `rejected` counts the step lengths refused.
template <typename Trial>
std::optional<EnergyPoint> BacktrackingLineSearch(const EnergyPoint& at, double slope,
                                                  const LineSearchOptions& options, Trial&& trial,
                                                  int* rejected = nullptr) {
  double alpha = 1.0;
  for (int t = 0; t < options.trials; ++t) {
    const EnergyPoint next = trial(alpha);
    const double roundoff = EnergyRoundoff(at.magnitude, next.magnitude);
    bool accepted = false;
    if (options.rule == RoundoffRule::kGradientDecides) {
      const bool sufficient_decrease = next.energy <= at.energy + options.armijo * alpha * slope;
      const bool roundoff_progress =
          std::abs(next.energy - at.energy) <= roundoff && next.residual < at.residual;
      accepted = std::isfinite(next.energy) && (sufficient_decrease || roundoff_progress);
    } else {
      accepted = std::isfinite(next.energy) &&
                 next.energy <= at.energy + options.armijo * alpha * slope + roundoff;
    }
    if (accepted) return next;
    if (rejected) ++*rejected;
    alpha *= 0.5;
  }
  return std::nullopt;
}

// The Newton iteration from the point `at` (the solver holds its state and gradient), as named
// steps that `steps` provides:
//   const char* StopBeforeStep(int iterations, const EnergyPoint& at): the stop tests before
//       a step (converged, the iteration limit, an interruption) at the current point: nullptr
//       to go on, else why it stops ("" when the solver's own summary says it);
//   const char* Direction(double& slope): the Newton direction and its slope along the
//       gradient: nullptr, or why there is none;
//   EnergyPoint Trial(double alpha): the point at step length alpha along the direction;
//   const char* Accept(EnergyPoint& at): makes the last trial the current point (`at` holds
//       the line search's point already; the solver may evaluate it again): nullptr, or why
//       the iteration cannot go on from it;
//   void Reject(): after a line search that took no step.
// `iterations` counts the steps tried, `rejected` the step lengths refused. Returns why it
// stopped.
template <typename Steps>
const char* NewtonIterate(Steps& steps, EnergyPoint& at, const LineSearchOptions& search,
                          int& iterations, int* rejected = nullptr) {
  for (;;) {
    if (const char* why = steps.StopBeforeStep(iterations, at)) return why;
    double slope = 0.0;
    if (const char* why = steps.Direction(slope)) return why;
    ++iterations;
    const std::optional<EnergyPoint> accepted = BacktrackingLineSearch(
        at, slope, search, [&](double alpha) { return steps.Trial(alpha); }, rejected);
    if (!accepted) {
      steps.Reject();
      return "the line search found no decrease of the energy (round-off)";
    }
    at = *accepted;
    if (const char* why = steps.Accept(at)) return why;
  }
}

}  // namespace springfit
