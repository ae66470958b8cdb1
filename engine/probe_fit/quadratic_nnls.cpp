#include "engine/probe_fit/quadratic_nnls.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

#include "engine/runtime/options_check.h"

namespace springfit::response {
namespace {

double Value(const Matrix& H, const Vector& c, const Vector& x) {
  return 0.5 * x.dot(H * x) - c.dot(x);
}

}  // namespace

void QuadraticNnlsOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  check.Require(max_iterations >= 1, "max_iterations", max_iterations, "value >= 1");
  check.Require(tolerance > 0.0 && tolerance < 1.0, "tolerance", tolerance, "0 < value < 1");
  check.Require(ridge > 0.0 && ridge <= 1e-2, "ridge", ridge, "0 < value <= 1e-2");
  check.Require(fallback_ridge > 0.0 && fallback_ridge <= 1e-2, "fallback_ridge", fallback_ridge,
                "0 < value <= 1e-2");
  check.Require(bound_band > 0.0 && bound_band < 1.0, "bound_band", bound_band, "0 < value < 1");
  check.Require(armijo > 0.0 && armijo < 0.5, "armijo", armijo, "0 < value < 0.5");
  check.Require(max_halvings >= 1, "max_halvings", max_halvings, "value >= 1");
}

QuadraticNnlsResult SolveQuadraticNnls(const Matrix& H, const Vector& c, const Vector& start,
                                       const std::vector<bool>& fixed,
                                       const QuadraticNnlsOptions& options,
                                       Interruption* interruption) {
  options.Validate();
  const int m = static_cast<int>(c.size());
  const auto held = [&](int i) { return !fixed.empty() && fixed[static_cast<std::size_t>(i)]; };
  QuadraticNnlsResult r;
  r.x = start.size() == m ? Vector(start.cwiseMax(0.0)) : Vector(Vector::Zero(m));
  for (int i = 0; i < m; ++i)
    if (held(i)) r.x[i] = 0.0;
  const double scale = std::max(c.cwiseAbs().maxCoeff(), 1e-300);
  const double diagonal_scale = std::max(H.diagonal().maxCoeff(), 1e-300);
  r.value = Value(H, c, r.x);
  for (r.iterations = 0; r.iterations < options.max_iterations; ++r.iterations) {
    if (interruption && interruption->Check()) throw Interrupted();
    const Vector g = H * r.x - c;
    // The free variables: away from the bound, or near it with a gradient pointing inside.
    // "Near" is Bertsekas' epsilon: as wide as the projected (diagonally scaled) gradient
    // step, so that variables on their way to 0 are fixed together rather than one per
    // iteration, and narrowing to 0 at the solution.
    double wide = 0.0;
    for (int i = 0; i < m; ++i) {
      if (held(i)) continue;
      const double diagonal = std::max(H(i, i), 1e-300);
      wide = std::max(wide, std::abs(r.x[i] - std::max(r.x[i] - g[i] / diagonal, 0.0)));
    }
    const double eps = std::min(options.bound_band * std::max(r.x.maxCoeff(), 1.0), wide);
    std::vector<int> free;
    double projected = 0.0;
    for (int i = 0; i < m; ++i) {
      if (held(i)) continue;
      const bool at_bound = r.x[i] <= eps && g[i] > 0.0;
      if (!at_bound) free.push_back(i);
      projected = std::max(projected, std::abs(r.x[i] > 0.0 ? g[i] : std::min(g[i], 0.0)));
    }
    if (projected <= options.tolerance * scale || free.empty()) {
      r.converged = true;
      break;
    }
    const int f = static_cast<int>(free.size());
    Matrix Hf(f, f);
    Vector gf(f);
    for (int a = 0; a < f; ++a) {
      gf[a] = g[free[static_cast<std::size_t>(a)]];
      for (int b = 0; b < f; ++b)
        Hf(a, b) = H(free[static_cast<std::size_t>(a)], free[static_cast<std::size_t>(b)]);
    }
    Hf.diagonal().array() += options.ridge * diagonal_scale;
    Eigen::LLT<Matrix> llt(Hf);
    if (llt.info() != Eigen::Success) {
      Hf.diagonal().array() += options.fallback_ridge * diagonal_scale;
      llt.compute(Hf);
    }
    const Vector step = llt.solve(-gf);
    Vector direction = Vector::Zero(m);
    for (int a = 0; a < f; ++a) direction[free[static_cast<std::size_t>(a)]] = step[a];
    // Armijo along the projected arc.
    double alpha = 1.0;
    bool moved = false;
    for (int halving = 0; halving < options.max_halvings; ++halving, alpha *= 0.5) {
      const Vector trial = (r.x + alpha * direction).cwiseMax(0.0);
      const double value = Value(H, c, trial);
      if (value <= r.value + options.armijo * g.dot(trial - r.x)) {
        moved = value < r.value || (trial - r.x).norm() == 0.0;
        r.x = trial;
        r.value = value;
        break;
      }
    }
    if (!moved) {
      r.converged = true;  // no descent left within round-off
      break;
    }
  }
  return r;
}

}  // namespace springfit::response
