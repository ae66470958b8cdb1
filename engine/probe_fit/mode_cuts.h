// Every mode held during the fit (response_fit.h, "Held modes"): a penalty on the Rayleigh
// quotients of the modes the fit's models left soft.
//
// The smallest generalised eigenvalue of (K_model, K_ref) on a support is the minimum over
// displacements v of v^T K_model v / v^T K_ref v, and K_model = sum_e k_e g_e g_e^T is linear
// in the stiffness k: along a fixed v the quotient is a . k with a_e = delta_e(v)^2 /
// v^T K_ref v (ModeSlope), delta_e(v) = g_e^T v the elongation of spring e. So lambda_min(k) is
// concave, the set {k : lambda_min(k) >= target} is convex, and each mode v a model left below
// the target gives a linear cut a . k >= target that every model holding the modes satisfies:
// cutting planes for the pencil's bound. The fit adds a cut for every soft mode of every model
// it judges and minimises, beside its objective,
//   weight * sum_j max(0, target - a_j . k)^2,
// a penalty that is zero on every model holding the modes it has met, and pushes the fit away
// from the modes it left soft before, so that the weak Tikhonov pulls, which fit the probes
// more closely, no longer buy that with a soft mode (bench/RESULTS.md, "Held modes"). A mode
// that stays soft over several judged models is cut once per model, nearly the same cut each
// time, so the pull on it grows until it is held; the weight was chosen with that so.
#pragma once

#include <string>
#include <vector>

#include "engine/probe_fit/gene_springs.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/problem/support_system.h"

namespace springfit::response {

struct ModeHoldOptions {
  // The penalty's weight (>= 0; 0: no cuts), in units of the fitted objective (a mean squared
  // relative error) per squared eigenvalue shortfall.
  double weight = 0.1;
  // The eigenvalue the cuts hold (> 0): a little above the fit's min_lambda, as the cuts are
  // met only once the fit has stepped past them.
  double target = 0.15;
  // Soft modes cut per user support and judged model (>= 1), and cuts kept at most (>= 1; the
  // oldest leave first: each holds one double per gene).
  int modes_per_support = 4;
  int max_cuts = 64;
  void Validate(const std::string& owner = "ModeHoldOptions") const;
};

// a_e = delta_e(v)^2 / v^T K_ref v for every gene, v the mode's shape: the derivative of the
// mode's Rayleigh quotient in each stiffness.
Vector ModeSlope(const GeneSprings& springs, const SoftMode& mode, const SupportSystem& reference);

// The cuts, in the fit's scaled variables x = k / scale.
class ModeCuts {
 public:
  ModeCuts(const ModeHoldOptions& options, Vector scale);

  bool enabled() const { return options_.weight > 0.0; }
  int size() const { return static_cast<int>(cuts_.size()); }
  const ModeHoldOptions& options() const { return options_; }

  void Add(const GeneSprings& springs, const SoftMode& mode, const SupportSystem& reference);

  // The penalty at x; half its gradient; half its Gauss-Newton Hessian (the cuts active at x)
  // times v, and that Hessian's diagonal. (Halves: the fits' objectives are sums of squares
  // whose gradient and normal matrix they carry halved.)
  double Penalty(const Vector& x) const;
  Vector HalfGradient(const Vector& x) const;
  Vector HalfHessianProduct(const Vector& x, const Vector& v) const;
  Vector HalfHessianDiagonal(const Vector& x) const;

 private:
  double Shortfall(std::size_t j, const Vector& x) const;

  ModeHoldOptions options_;
  Vector scale_;
  std::vector<Vector> cuts_;  // a_j * scale, per gene
};

}  // namespace springfit::response
