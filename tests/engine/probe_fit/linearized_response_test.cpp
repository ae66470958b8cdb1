// The matrix-free fit's linearisation (engine/probe_fit/linearized_response.h): its operators
// against finite differences, and its factorisations reused by the judgements.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "engine/probe_fit/gene_springs.h"
#include "engine/probe_fit/linearized_response.h"
#include "engine/probe_fit/probe_bank.h"
#include "engine/probe_fit/probe_objective.h"
#include "engine/probe_fit/response_fit.h"
#include "engine/problem/baseline_evaluation.h"
#include "engine/problem/rest_stiffness.h"
#include "io/example_catalog.h"
#include "tests/engine/probe_fit/probe_fit_test_support.h"

namespace springfit::response {
namespace {

// The matrix-free fit's operators (linearized_response.h) against finite differences of the
// exact residuals: J^T r is half the objective's gradient, and v^T J^T J v = |J v|^2 with J v the
// residuals' derivative along v; J^T J is symmetric.
TEST(LinearizedResponse, GradientAndNormalProductMatchFiniteDifferences) {
  const Problem problem(examples::Make("fem-plate-5x5"));
  const SparseMatrix k = ReferenceRestStiffness(problem);
  ResponseFitOptions options;
  options.dust = 0.0;
  const ProbeBank bank = MakeProbeBanks(problem, k, options.probes).fit;
  const std::vector<double> prior = *BaselineGeneWeights(problem);
  const ProbeObjective objective(problem, bank, k, prior, options);
  const GeneSprings springs = GeneSpringsOf(problem);
  const Vector x = objective.Scaled(prior);
  // A direction that keeps every present spring present and every absent one absent.
  Vector u(x.size()), v(x.size());
  for (Eigen::Index e = 0; e < x.size(); ++e) {
    u[e] = x[e] > 0.0 ? std::sin(1.0 + 3.0 * static_cast<double>(e)) : 0.0;
    v[e] = x[e] > 0.0 ? std::cos(2.0 + 5.0 * static_cast<double>(e)) : 0.0;
  }
  const auto residuals = [&](const Vector& at) {
    LinearizedResponse l(objective, springs);
    EXPECT_TRUE(l.At(objective.Weights(at)));
    return l.Residuals();
  };
  LinearizedResponse at(objective, springs);
  ASSERT_TRUE(at.At(objective.Weights(x)));
  const double h = 1e-5;
  const Vector jv = (residuals(x + h * v) - residuals(x - h * v)) / (2.0 * h);
  const Vector r = at.Residuals();
  // d/dt |r(x + t v)|^2 = 2 r^T J v = 2 (J^T r)^T v.
  EXPECT_NEAR(at.Gradient().dot(v), r.dot(jv), 1e-6 * std::abs(r.dot(jv)));
  EXPECT_NEAR(v.dot(at.NormalProduct(v)), jv.squaredNorm(), 1e-6 * jv.squaredNorm());
  const double uhv = u.dot(at.NormalProduct(v)), vhu = v.dot(at.NormalProduct(u));
  EXPECT_NEAR(uhv, vhu, 1e-10 * std::abs(uhv) + 1e-14);
  EXPECT_NEAR(at.ResidualNorm2(), r.squaredNorm(), 1e-12 * r.squaredNorm());
  // The diagonal's estimate: positive, and of the order of the exact one on a few genes.
  const Vector diagonal = at.NormalDiagonal(64, 1);
  for (Eigen::Index e = 0; e < x.size(); e += 17) {
    if (!(x[e] > 0.0)) continue;
    Vector unit = Vector::Zero(x.size());
    unit[e] = 1.0;
    const double exact = at.NormalProduct(unit)[e];
    EXPECT_GT(diagonal[e], 0.3 * exact) << e;
    EXPECT_LT(diagonal[e], 3.0 * exact) << e;
  }
}

// The judgements of a linearised model reuse its factorisations, supports matched by index:
// the same choosing error and eigenvalue bound, bit for bit, as factorising anew; on a model
// the linearisation does not hold, its factorisations would give other numbers.
TEST(LinearizedResponse, ItsFactorisationsJudgeItsModelAsFactorisingAnew) {
  const KidneyAtRest kidney;
  const std::vector<double>& prior = kidney.prior;
  const ProbeObjective objective(kidney.problem, kidney.bank, kidney.k, prior, kidney.options);
  const GeneSprings springs = GeneSpringsOf(kidney.problem);
  LinearizedResponse at(objective, springs);
  ASSERT_TRUE(at.At(prior));
  ASSERT_GE(objective.fitted_supports().size(), 2u);
  EXPECT_EQ(objective.SelectError(prior, at.Factorized()), objective.SelectError(prior));
  EXPECT_EQ(objective.LambdaMin(prior, at.Factorized()), objective.LambdaMin(prior));
  std::vector<double> other = prior;
  for (std::size_t e = 0; e < other.size(); e += 3) other[e] *= 2.0;
  EXPECT_NE(objective.SelectError(other, at.Factorized()), objective.SelectError(other));
}

}  // namespace
}  // namespace springfit::response
