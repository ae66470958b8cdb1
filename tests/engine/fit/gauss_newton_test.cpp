// The fitting core's driver (engine/fit/gauss_newton.h) on objectives whose answers are known:
// bounded linear least squares (its answer the dense NNLS's) and Rosenbrock's valley as a
// residual (curved: the Gauss-Newton model is poor far from the minimum).
#include "engine/fit/gauss_newton.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "engine/linalg/nnls.h"

namespace springfit {
namespace {

// Phi = 1/2 |r(x)|^2 with r and its Jacobian given; x >= 0 where `bounded`, and no model where
// `feasible` says so.
struct Residual {
  std::function<Vector(const Vector&)> r;
  std::function<Matrix(const Vector&)> jacobian;
  bool bounded = false;
  std::function<bool(const Vector&)> feasible = [](const Vector&) { return true; };
  bool jacobi = false;  // precondition with J^T J's diagonal
  // What the driver asked of its points (GaussNewtonPoint::Idle): idle points, trials made
  // while their point was not idle, and operators asked of an idle point (it rebuilds them).
  struct IdleLog {
    int idles = 0;
    int trials_of_busy_points = 0;
    int operators_of_idle_points = 0;
  };
  std::shared_ptr<IdleLog> log = std::make_shared<IdleLog>();
};

class TestPoint : public GaussNewtonPoint {
 public:
  TestPoint(const Residual& f, Vector x)
      : f_(f), x_(std::move(x)), r_(f.r(x_)), j_(f.jacobian(x_)) {}
  double Value() const override { return 0.5 * r_.squaredNorm(); }
  Vector Gradient() const override {
    Wake();
    return j_.transpose() * r_;
  }
  Vector NormalProduct(const Vector& v) const override {
    Wake();
    return j_.transpose() * (j_ * v);
  }
  Vector NormalDiagonal() const override {
    Wake();
    return f_.jacobi ? Vector(j_.colwise().squaredNorm().transpose()) : Vector::Ones(x_.size());
  }
  std::vector<bool> Free(const Vector& g) const override {
    std::vector<bool> free(static_cast<std::size_t>(x_.size()));
    for (Eigen::Index i = 0; i < x_.size(); ++i)
      free[static_cast<std::size_t>(i)] = !(f_.bounded && x_[i] <= 0.0 && g[i] > 0.0);
    return free;
  }
  Vector Taken(const Vector& d, double t) const override {
    return f_.bounded ? Vector((x_ + t * d).cwiseMax(0.0) - x_) : Vector(t * d);
  }
  void Idle() override {
    idle_ = true;
    ++f_.log->idles;
  }
  std::unique_ptr<GaussNewtonPoint> Trial(const Vector& d, double t) const override {
    if (!idle_) ++f_.log->trials_of_busy_points;
    const Vector x = x_ + Taken(d, t);
    if (!f_.feasible(x)) return nullptr;
    return std::make_unique<TestPoint>(f_, x);
  }
  const Vector& x() const { return x_; }

 private:
  void Wake() const {
    if (idle_) ++f_.log->operators_of_idle_points;
    idle_ = false;
  }

  const Residual& f_;
  Vector x_;
  Vector r_;
  Matrix j_;
  mutable bool idle_ = false;
};

const Vector& X(const std::unique_ptr<GaussNewtonPoint>& p) {
  return static_cast<const TestPoint&>(*p).x();
}

// A 6 x 4 system whose unbounded least-squares solution has a negative entry.
Residual BoundedLinear(Matrix& a, Vector& b) {
  a.resize(6, 4);
  a << 1, 0.5, 0, 0.2, 0.3, 1, 0.1, 0, 0, 0.4, 1, 0.3, 0.2, 0, 0.3, 1, 1, 1, 0, 0, 0, 0.2, 1, 1;
  b.resize(6);
  b << 1, -2, 0.5, 1, -0.5, 2;
  Residual f;
  f.r = [a, b](const Vector& x) { return Vector(a * x - b); };
  f.jacobian = [a](const Vector&) { return a; };
  f.bounded = true;
  return f;
}

TEST(GaussNewton, BothGlobalisationsReachTheBoundedLeastSquaresSolution) {
  Matrix a;
  Vector b;
  Residual f = BoundedLinear(a, b);
  const Vector unbounded = a.colPivHouseholderQr().solve(b);
  ASSERT_LT(unbounded.minCoeff(), 0.0);  // the bound is active
  const NnlsResult exact = SolveDenseNnls(a, b, std::vector<bool>(4, true));
  for (const bool trust_region : {false, true}) {
    for (const bool jacobi : {false, true}) {
      SCOPED_TRACE(::testing::Message()
                   << "trust region " << trust_region << ", jacobi " << jacobi);
      f.jacobi = jacobi;
      GaussNewtonOptions options;
      options.max_steps = 100;
      options.cg_tolerance = 1e-12;
      options.halvings = 30;
      if (trust_region) {
        options.initial_radius = 0.1;  // (small: the region has to grow)
        options.max_radius = 1e3;
      }
      std::unique_ptr<GaussNewtonPoint> point =
          std::make_unique<TestPoint>(f, Vector::Constant(4, 1.0));
      int accepted = 0;
      const GaussNewtonOutcome outcome =
          DescendGaussNewton(point, options, [&](const GaussNewtonPoint&) { ++accepted; });
      EXPECT_TRUE(outcome.converged);
      EXPECT_EQ(outcome.accepted, accepted);
      EXPECT_LE(outcome.accepted, outcome.steps);
      for (int i = 0; i < 4; ++i) {
        EXPECT_NEAR(X(point)[i], exact.x[i], 1e-8 * exact.x.norm()) << "entry " << i;
        if (exact.x[i] == 0.0) EXPECT_EQ(X(point)[i], 0.0) << "entry " << i << " off its bound";
      }
    }
  }
}

// Rosenbrock's function as a residual, r = (10 (x2 - x1^2), 1 - x1), minimum 0 at (1, 1).
Residual Rosenbrock() {
  Residual f;
  f.r = [](const Vector& x) {
    Vector r(2);
    r << 10.0 * (x[1] - x[0] * x[0]), 1.0 - x[0];
    return r;
  };
  f.jacobian = [](const Vector& x) {
    Matrix j(2, 2);
    j << -20.0 * x[0], 10.0, -1.0, 0.0;
    return j;
  };
  return f;
}

TEST(GaussNewton, TheTrustRegionCrossesACurvedValleyAndNeverStepsWhereThereIsNoModel) {
  Residual f = Rosenbrock();
  // No model below x2 = -1 (as a spring model without equilibrium): the first Gauss-Newton
  // step from the far start lands there (at x2 = -3.84) and is refused, the region shrinks and
  // the descent goes on around.
  int refused = 0;
  f.feasible = [&refused](const Vector& x) {
    const bool ok = x[1] >= -1.0;
    refused += ok ? 0 : 1;
    return ok;
  };
  GaussNewtonOptions options;
  options.max_steps = 200;
  options.cg_tolerance = 1e-12;
  options.initial_radius = 10.0;
  options.max_radius = 100.0;
  Vector start(2);
  start << -1.2, 1.0;
  std::unique_ptr<GaussNewtonPoint> point = std::make_unique<TestPoint>(f, start);
  std::vector<double> values;
  options.target_value = 1e-20;
  const GaussNewtonOutcome outcome = DescendGaussNewton(
      point, options, [&](const GaussNewtonPoint& p) { values.push_back(p.Value()); });
  EXPECT_TRUE(outcome.converged);
  EXPECT_GT(refused, 0);
  EXPECT_LT(outcome.accepted, outcome.steps);  // some steps refused, the region shrunk
  EXPECT_NEAR(X(point)[0], 1.0, 1e-8);
  EXPECT_NEAR(X(point)[1], 1.0, 1e-8);
  for (std::size_t i = 1; i < values.size(); ++i) EXPECT_LT(values[i], values[i - 1]);
}

// The line search reads only its trials' values once the step is computed, so it lets the point
// go idle before its first trial (the nonlinear stage then keeps one set of factorised tangents
// alive, not the point's and the trial's); the trust region, which asks the point again after
// a refused step, does not.
TEST(GaussNewton, TheLineSearchLetsItsPointIdleWhileItTriesSteps) {
  Matrix a;
  Vector b;
  const Residual f = BoundedLinear(a, b);
  GaussNewtonOptions options;
  options.cg_iterations = 1;  // (one CG iteration per step: many steps)
  options.max_steps = 30;
  const Vector start = Vector::Constant(4, 1.0);
  std::unique_ptr<GaussNewtonPoint> point = std::make_unique<TestPoint>(f, start);
  const GaussNewtonOutcome line = DescendGaussNewton(point, options);
  EXPECT_GT(line.steps, 10);
  // (every step that reached its line search; a last step can end stationary before it)
  EXPECT_GE(f.log->idles, line.steps - 1);
  EXPECT_LE(f.log->idles, line.steps);
  EXPECT_EQ(f.log->trials_of_busy_points, 0);
  EXPECT_EQ(f.log->operators_of_idle_points, 0);

  // (Rosenbrock's valley, where the trust region refuses steps and shrinks)
  const Residual valley = Rosenbrock();
  GaussNewtonOptions region_options;
  region_options.max_steps = 50;
  region_options.initial_radius = 10.0;
  region_options.max_radius = 100.0;
  Vector far(2);
  far << -1.2, 1.0;
  point = std::make_unique<TestPoint>(valley, far);
  const GaussNewtonOutcome region = DescendGaussNewton(point, region_options);
  EXPECT_GT(region.steps, region.accepted);  // (refused steps ask the point again)
  EXPECT_EQ(valley.log->idles, 0);
}

TEST(GaussNewton, AStopKeepsTheLastAcceptedPoint) {
  Matrix a;
  Vector b;
  const Residual f = BoundedLinear(a, b);
  Interruption interruption;
  GaussNewtonOptions options;
  options.cg_iterations = 1;  // (one CG iteration per step: many steps)
  Vector last;
  std::unique_ptr<GaussNewtonPoint> point =
      std::make_unique<TestPoint>(f, Vector::Constant(4, 1.0));
  int accepted = 0;
  EXPECT_THROW(DescendGaussNewton(
                   point, options,
                   [&](const GaussNewtonPoint& p) {
                     last = static_cast<const TestPoint&>(p).x();
                     if (++accepted == 3) interruption.Request();
                   },
                   &interruption),
               Interrupted);
  EXPECT_EQ(accepted, 3);
  EXPECT_EQ(X(point), last);
}

TEST(GaussNewton, OptionsAreCheckedAtTheEntry) {
  Matrix a;
  Vector b;
  const Residual f = BoundedLinear(a, b);
  std::unique_ptr<GaussNewtonPoint> point =
      std::make_unique<TestPoint>(f, Vector::Constant(4, 1.0));
  GaussNewtonOptions options;
  options.initial_radius = 2.0;
  options.max_radius = 1.0;
  EXPECT_THROW(DescendGaussNewton(point, options), std::invalid_argument);
}

}  // namespace
}  // namespace springfit
