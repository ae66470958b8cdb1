// The fitting core's one driver (docs/ARCHITECTURE.md, "The fitting core"): projected
// Gauss-Newton over any objective that can state, at a point, its value, its gradient, its
// Gauss-Newton product and an estimate of that product's diagonal. The named-case fit
// (stiffness_fit.h), the rest-linear probe fit and its nonlinear stage
// (engine/probe_fit/matrix_free_fit.h) are objectives on it; each says what its variables are
// and where their bounds lie, the driver only steps.
//
// Each step, at the point x with the objective Phi:
//   1. g = the gradient in the point's step coordinates (J^T r for Phi = 1/2 |r|^2; for
//      Phi = |r|^2 the half gradient, also J^T r: the step is the same);
//   2. the free coordinates: those not held at a bound the gradient pushes them past;
//   3. the Gauss-Newton system N d = -g on the free coordinates (N = J^T J plus the penalties'
//      curvature), by conjugate gradients preconditioned with N's diagonal as the point
//      estimates it (ones: none);
//   4. the step's globalisation, one of two:
//      - the line search (initial_radius 0): the point at t d projected onto the bounds,
//        t = 1, 1/2, 1/4, ... until Phi falls (Bertsekas' projected arc), at most `halvings`
//        trials; none falling ends the descent. Cheap where the objective is near quadratic
//        in the stiffness, as the rest-linear probe fit's is;
//      - the trust region (initial_radius > 0): CG truncated at the radius (Steihaug), the
//        step cut at the bounds tried once (and once more stopped short of them when it
//        fails), accepted when Phi falls by a fair share of what the Gauss-Newton model
//        predicts, the radius grown or shrunk with that agreement. Where the response is far
//        from quadratic (equilibria near a mechanism after springs are pruned, nonlinear
//        springs) the radius remembers how far the model can be trusted, which a line search
//        restarted at t = 1 forgets (bench/RESULTS.md, round fifteen).
// The driver is deterministic: all randomness (the diagonal's estimate) is the point's, seeded.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "engine/linalg/linalg.h"
#include "engine/runtime/interruption.h"

namespace springfit {

// One point of an objective: a model with its equilibria solved and its operators ready.
class GaussNewtonPoint {
 public:
  virtual ~GaussNewtonPoint() = default;
  // Phi, what the descent lowers.
  virtual double Value() const = 0;
  // In the point's step coordinates (see above).
  virtual Vector Gradient() const = 0;
  virtual Vector NormalProduct(const Vector& v) const = 0;
  virtual Vector NormalDiagonal() const = 0;
  // Per coordinate, whether it moves in this step, given the gradient.
  virtual std::vector<bool> Free(const Vector& gradient) const = 0;
  // The step Trial(d, t) takes, in step coordinates: t d cut at the bounds.
  virtual Vector Taken(const Vector& d, double t) const = 0;
  // The trust region's second try when the step cut at the bounds fails: d stopped short of
  // them (d itself: no second try).
  virtual Vector ShortOfBounds(const Vector& d) const { return d; }
  // The point t d away, projected onto the bounds; nullptr when there is no model there (no
  // equilibrium, no springs). Throws Interrupted when stopped.
  virtual std::unique_ptr<GaussNewtonPoint> Trial(const Vector& d, double t) const = 0;
  // Called by the line search once the step is computed: until a trial is accepted or the
  // search gives up, it reads only the trials' values, so the point may release what its
  // operators need (the nonlinear stage's factorised tangents: one set alive instead of the
  // point's and its trial's) and rebuild it if they are asked for again. Nothing by default.
  virtual void Idle() {}
};

struct GaussNewtonOptions {
  int max_steps = 200;         // steps tried, accepted or not
  int cg_iterations = 40;      // conjugate-gradient iterations per step (one product each)
  double cg_tolerance = 1e-3;  // CG stops below this fraction of its initial residual
  int halvings = 4;            // line search: trials per step, t = 1, 1/2, ..., 2^-(halvings - 1)
  // The trust region's first radius, in the step coordinates' 2-norm; 0: the line search.
  double initial_radius = 0.0;
  // Its largest radius. Near a rigid or a mechanism limit the response stops following the
  // variables, which the Gauss-Newton model cannot see: this only keeps a step finite.
  double max_radius = 0.0;
  // Converged when two accepted steps in a row lower Phi by less than this fraction of it
  // (0: the descent runs its steps, or until no step lowers Phi).
  double relative_tolerance = 0.0;
  // Converged once Phi is at or below this (an exact fit: nothing is left to lower).
  double target_value = 0.0;

  // Throws std::invalid_argument naming the field, its value and the rule it breaks.
  void Validate(const std::string& owner = "GaussNewtonOptions") const;
};

struct GaussNewtonOutcome {
  int steps = 0;     // steps tried
  int accepted = 0;  // steps that lowered Phi
  // Ended before the step limit: by the tolerance, the target, a vanishing free gradient, a
  // line search whose trials found no lower Phi (a minimum along the arc to within its last
  // trial), or a trust region shrunk below 1e-12.
  bool converged = false;
};

// Called after every accepted step with the new point.
using GaussNewtonAccepted = std::function<void(const GaussNewtonPoint&)>;

// Descends from `point`, which follows every accepted step. `interruption`, when set, is
// checked before every step and throws Interrupted; `point` is then the last accepted one.
GaussNewtonOutcome DescendGaussNewton(std::unique_ptr<GaussNewtonPoint>& point,
                                      const GaussNewtonOptions& options,
                                      const GaussNewtonAccepted& on_accept = {},
                                      Interruption* interruption = nullptr);

}  // namespace springfit
