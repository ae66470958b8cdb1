// The held modes' cuts (engine/probe_fit/mode_cuts.h): a cut is its mode's Rayleigh quotient and
// the penalty its squared shortfall, with the penalty's derivatives.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "engine/probe_fit/gene_springs.h"
#include "engine/probe_fit/mode_cuts.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/probe_fit/probe_objective.h"
#include "engine/problem/rest_stiffness.h"
#include "engine/problem/support_system.h"
#include "tests/engine/probe_fit/probe_fit_test_support.h"

namespace springfit::response {
namespace {

// A cut is the Rayleigh quotient of its mode, linear in the stiffness: at the model whose soft
// mode it was made from it gives that mode's eigenvalue; the penalty is zero where every cut is
// met, and its half gradient and half Hessian are those of the penalty (finite differences).
TEST(ModeCuts, ACutIsItsModesRayleighQuotientAndThePenaltyItsSquaredShortfall) {
  const KidneyAtRest kidney;
  const GeneSprings springs = GeneSpringsOf(kidney.problem);
  const Vector scale = PriorScale(kidney.prior);
  // A model soft somewhere: the baseline with every spring of one node's star at a thousandth.
  std::vector<double> weights = kidney.prior;
  const int node = kidney.problem.scene().node_count() / 2;
  for (std::size_t g = 0; g < weights.size(); ++g)
    if (springs.pairs[g].first == node || springs.pairs[g].second == node) weights[g] *= 1e-3;
  const std::size_t user = kidney.bank.supports[0].user ? 0 : 1;
  ASSERT_TRUE(kidney.bank.supports[user].user);
  SupportSystem reference(2, kidney.bank.supports[user].constrained);
  ASSERT_TRUE(reference.Factorize(kidney.k));
  const std::vector<SoftMode> modes =
      SoftModes(SpringRestStiffness(kidney.problem, weights), reference, 0.15, 2);
  ASSERT_EQ(modes.size(), 2u);
  ModeHoldOptions options;
  options.weight = 0.1;
  options.target = 0.15;
  ModeCuts cuts(options, scale);
  for (const SoftMode& mode : modes) cuts.Add(springs, mode, reference);
  Vector x(static_cast<Eigen::Index>(weights.size()));
  for (std::size_t g = 0; g < weights.size(); ++g)
    x[static_cast<Eigen::Index>(g)] = weights[g] / scale[static_cast<Eigen::Index>(g)];
  // Each cut at the model is its mode's eigenvalue (a Ritz pair: its Rayleigh quotient), so the
  // penalty is the sum of their squared shortfalls.
  double shortfalls = 0.0;
  for (const SoftMode& mode : modes) {
    EXPECT_NEAR(ModeSlope(springs, mode, reference).dot(Vector::Map(weights.data(), x.size())),
                mode.lambda, 1e-6 * mode.lambda);
    shortfalls += std::pow(0.15 - mode.lambda, 2);
  }
  EXPECT_NEAR(cuts.Penalty(x), 0.1 * shortfalls, 1e-6 * 0.1 * shortfalls);
  // Finite differences along a random direction.
  std::mt19937_64 random(3);
  std::normal_distribution<double> normal;
  Vector v(x.size());
  for (Eigen::Index e = 0; e < v.size(); ++e) v[e] = normal(random);
  const double h = 1e-6 * x.norm() / v.norm();
  const double slope = (cuts.Penalty(x + h * v) - cuts.Penalty(x - h * v)) / (2.0 * h);
  EXPECT_NEAR(2.0 * cuts.HalfGradient(x).dot(v), slope, 1e-5 * std::abs(slope));
  const double curvature =
      (cuts.Penalty(x + h * v) - 2.0 * cuts.Penalty(x) + cuts.Penalty(x - h * v)) / (h * h);
  EXPECT_NEAR(2.0 * v.dot(cuts.HalfHessianProduct(x, v)), curvature, 1e-3 * curvature);
  for (Eigen::Index e = 0; e < x.size(); e += 37) {
    Vector unit = Vector::Zero(x.size());
    unit[e] = 1.0;
    EXPECT_NEAR(cuts.HalfHessianDiagonal(x)[e], cuts.HalfHessianProduct(x, unit)[e],
                1e-12 * (1.0 + cuts.HalfHessianDiagonal(x)[e]));
  }
  // Stiffened past every cut, the penalty and its derivatives vanish.
  const Vector stiff = 1e3 * x;
  EXPECT_EQ(cuts.Penalty(stiff), 0.0);
  EXPECT_EQ(cuts.HalfGradient(stiff).norm(), 0.0);
  EXPECT_EQ(cuts.HalfHessianProduct(stiff, v).norm(), 0.0);
}

}  // namespace
}  // namespace springfit::response
