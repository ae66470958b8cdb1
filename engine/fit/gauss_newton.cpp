#include "engine/fit/gauss_newton.h"

#include <cmath>

#include "engine/runtime/options_check.h"

namespace springfit {
namespace {

// A trust region this small (in the step coordinates) has stopped moving the point.
constexpr double kSmallestRadius = 1e-12;
// A trial is accepted when it achieves at least this fraction of the decrease the
// Gauss-Newton model predicts (trust region only).
constexpr double kAcceptedAgreement = 1e-4;

// The step of conjugate gradients and the residual it left.
struct CgStep {
  Vector d;
  Vector residual;
};

// tau >= 0 with |d + tau p| = radius.
double ToBoundary(const Vector& d, const Vector& p, double radius) {
  const double a = p.squaredNorm(), b = 2.0 * d.dot(p), c = d.squaredNorm() - radius * radius;
  return (-b + std::sqrt(std::max(b * b - 4.0 * a * c, 0.0))) / (2.0 * a);
}

// Preconditioned conjugate gradients for N d = b on the entries where `free` holds (d is 0
// elsewhere); at most `iterations`, or until the residual falls below `tolerance` |b|. With
// radius > 0 Steihaug's truncation: a step that would leave the ball |d| <= radius, or a
// direction N does not curve up along, ends at the ball's boundary. (Eigen's
// ConjugateGradient takes a matrix-free operator only as a sparse-matrix-like expression type;
// a closure over the masked products is the shorter and clearer form here.)
CgStep ConjugateGradients(const GaussNewtonPoint& point, const Vector& b, const Vector& diagonal,
                          const std::vector<bool>& free, int iterations, double tolerance,
                          double radius) {
  const Eigen::Index m = b.size();
  Vector mask(m);
  for (Eigen::Index e = 0; e < m; ++e) mask[e] = free[static_cast<std::size_t>(e)] ? 1.0 : 0.0;
  Vector d = Vector::Zero(m);
  Vector r = b.cwiseProduct(mask);
  const double target = tolerance * r.norm();
  Vector z = r.cwiseQuotient(diagonal);
  Vector p = z;
  double rz = r.dot(z);
  for (int it = 0; it < iterations && r.norm() > target; ++it) {
    const Vector ap = point.NormalProduct(p).cwiseProduct(mask);
    const double curvature = p.dot(ap);
    const double alpha = rz / curvature;
    if (radius > 0.0 && (!(curvature > 0.0) || (d + alpha * p).norm() >= radius)) {
      const double tau = ToBoundary(d, p, radius);
      d += tau * p;
      r -= tau * ap;
      break;
    }
    if (!(curvature > 0.0)) break;
    d += alpha * p;
    r -= alpha * ap;
    z = r.cwiseQuotient(diagonal);
    const double rz_next = r.dot(z);
    p = z + (rz_next / rz) * p;
    rz = rz_next;
  }
  return {d, r};
}

}  // namespace

void GaussNewtonOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  check.Require(max_steps >= 0, "max_steps", max_steps, "value >= 0");
  check.Require(cg_iterations >= 1, "cg_iterations", cg_iterations, "value >= 1");
  check.Require(InOpenUnit(cg_tolerance), "cg_tolerance", cg_tolerance, "0 < value < 1");
  check.Require(halvings >= 1, "halvings", halvings, "value >= 1");
  check.Require(initial_radius >= 0.0 && std::isfinite(initial_radius), "initial_radius",
                initial_radius, "0 <= value < infinity (0: the line search)");
  check.Require(max_radius >= initial_radius && std::isfinite(max_radius), "max_radius", max_radius,
                "initial_radius <= value < infinity");
  check.Require(relative_tolerance >= 0.0 && relative_tolerance < 1.0, "relative_tolerance",
                relative_tolerance, "0 <= value < 1");
  check.Require(target_value >= 0.0 && std::isfinite(target_value), "target_value", target_value,
                "0 <= value < infinity");
}

GaussNewtonOutcome DescendGaussNewton(std::unique_ptr<GaussNewtonPoint>& point,
                                      const GaussNewtonOptions& options,
                                      const GaussNewtonAccepted& on_accept,
                                      Interruption* interruption) {
  options.Validate();
  GaussNewtonOutcome outcome;
  const bool trust_region = options.initial_radius > 0.0;
  double radius = options.initial_radius;
  int small_decreases = 0;
  while (outcome.steps < options.max_steps) {
    // (Phi again at every step: the point's penalties may have changed with the last
    // acceptance, the probe fit's held modes for one.)
    const double phi = point->Value();
    if (phi <= options.target_value) {
      outcome.converged = true;
      break;
    }
    ThrowIfInterrupted(interruption);
    ++outcome.steps;
    const Vector gradient = point->Gradient();
    const std::vector<bool> free = point->Free(gradient);
    bool moves = false;
    for (Eigen::Index e = 0; e < gradient.size() && !moves; ++e)
      moves = free[static_cast<std::size_t>(e)] && gradient[e] != 0.0;
    if (!moves) {  // stationary on the free coordinates
      outcome.converged = true;
      break;
    }
    const CgStep cg = ConjugateGradients(*point, -gradient, point->NormalDiagonal(), free,
                                         options.cg_iterations, options.cg_tolerance, radius);
    std::unique_ptr<GaussNewtonPoint> next;
    double value = phi;
    if (trust_region) {
      // A trial of the step z: its value and its agreement with the model's decrease
      // -(g.z + 1/2 z.N z) for the step taken (from CG's residual, N d = b - r with b = -g,
      // unless the bounds cut the step; then by one more product). Below kAcceptedAgreement
      // it is refused.
      const auto attempt = [&](const Vector& z, std::unique_ptr<GaussNewtonPoint>& trial) {
        const Vector taken = point->Taken(z, 1.0);
        const double predicted =
            taken == cg.d ? 0.5 * (cg.d.dot(-gradient) + cg.d.dot(cg.residual))
                          : -(gradient.dot(taken) + 0.5 * taken.dot(point->NormalProduct(taken)));
        trial = point->Trial(z, 1.0);
        if (!trial) return -1.0;
        value = trial->Value();
        const double actual = phi - value;
        // (A cut step can lower Phi with a model decrease <= 0: taken, the region kept.)
        return !(actual > 0.0) ? -1.0 : predicted > 0.0 ? actual / predicted : 0.5;
      };
      const double length = cg.d.norm();
      std::unique_ptr<GaussNewtonPoint> trial;
      double agreement = attempt(cg.d, trial);
      // A step the bounds cut that fails (near a mechanism the response grows like 1 / k,
      // which the model cannot see) is tried once more stopped short of them.
      if (!(agreement > kAcceptedAgreement) && point->Taken(cg.d, 1.0) != cg.d) {
        const Vector shorter = point->ShortOfBounds(cg.d);
        if (shorter != cg.d) agreement = attempt(shorter, trial);
      }
      if (agreement > kAcceptedAgreement) {
        next = std::move(trial);
        if (agreement > 0.75 && length >= 0.99 * radius)
          radius = std::min(2.0 * radius, options.max_radius);
        if (agreement < 0.25) radius = 0.25 * length;
      } else {
        radius = 0.25 * length;
        if (radius < kSmallestRadius) {
          outcome.converged = true;
          break;
        }
        continue;
      }
    } else {
      point->Idle();
      for (int halving = 0; halving < options.halvings && !next; ++halving) {
        std::unique_ptr<GaussNewtonPoint> trial = point->Trial(cg.d, std::ldexp(1.0, -halving));
        if (!trial) continue;
        value = trial->Value();
        if (value < phi) next = std::move(trial);
      }
      if (!next) {  // a minimum along the arc, to within its last trial
        outcome.converged = true;
        break;
      }
    }
    point = std::move(next);
    ++outcome.accepted;
    if (on_accept) on_accept(*point);
    small_decreases = phi - value < options.relative_tolerance * phi ? small_decreases + 1 : 0;
    if (options.relative_tolerance > 0.0 && small_decreases >= 2) {
      outcome.converged = true;
      break;
    }
  }
  return outcome;
}

}  // namespace springfit
