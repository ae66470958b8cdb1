// The pencil's eigenvalues (engine/probe_fit/probe_evaluation.h): its extremes against a dense
// generalised eigensolver, and the soft modes as its smallest eigenpairs; the probes' errors
// with the tool loads solved through their base's factor.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Eigenvalues>

#include "engine/probe_fit/probe_bank.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/problem/baseline_evaluation.h"
#include "engine/problem/rest_stiffness.h"
#include "engine/problem/support_system.h"
#include "io/example_catalog.h"

namespace springfit::response {
namespace {

TEST(PencilExtremes, MatchADenseGeneralisedEigensolver) {
  const Problem problem(examples::Make("fem-plate-5x5"));
  const SparseMatrix kref = ReferenceRestStiffness(problem);
  const SparseMatrix kb = SpringRestStiffness(problem, *BaselineGeneWeights(problem));
  const ProbeBank bank = MakeProbeBanks(problem, kref, ProbeOptions{}).fit;
  const Support& support = bank.supports[0];
  const PencilExtremes x = GeneralizedEigenvalueExtremes(kb, kref, support.constrained, 2);
  SupportSystem a(2, support.constrained), b(2, support.constrained);
  a.Factorize(kb);
  b.Factorize(kref);
  const int n = a.free_dofs();
  Matrix A(n, n), B(n, n);
  for (int j = 0; j < n; ++j) {
    A.col(j) = a.Multiply(Vector::Unit(n, j));
    B.col(j) = b.Multiply(Vector::Unit(n, j));
  }
  Eigen::GeneralizedSelfAdjointEigenSolver<Matrix> dense(A, B, Eigen::EigenvaluesOnly);
  EXPECT_NEAR(x.lambda_min, dense.eigenvalues().minCoeff(), 1e-6 * x.lambda_max);
  EXPECT_NEAR(x.lambda_max, dense.eigenvalues().maxCoeff(), 1e-6 * x.lambda_max);
  EXPECT_NEAR(x.Bound(), std::max(1.0 / x.lambda_min - 1.0, 1.0 - 1.0 / x.lambda_max), 1e-12);
}

// The soft modes are generalised eigenvectors: K_model v = lambda K_ref v on the free degrees of
// freedom, the smallest eigenvalue first and equal to SmallestGeneralizedEigenvalue's, nothing
// on the support's nodes.
TEST(PencilExtremes, SoftModesAreTheSmallestGeneralisedEigenpairs) {
  const Problem problem(examples::Make("fem-kidney-2d"));
  const SparseMatrix kref = ReferenceRestStiffness(problem);
  const SparseMatrix kb = SpringRestStiffness(problem, *BaselineGeneWeights(problem));
  const ProbeBank bank = MakeProbeBanks(problem, kref, ProbeOptions{}).fit;
  const Support& support = bank.supports[0];
  SupportSystem reference(2, support.constrained), model(2, support.constrained);
  ASSERT_TRUE(reference.Factorize(kref));
  ASSERT_TRUE(model.Factorize(kb));
  const std::vector<SoftMode> modes = SoftModes(kb, reference, 1.0, 3);
  ASSERT_EQ(modes.size(), 3u);
  EXPECT_EQ(modes[0].lambda, SmallestGeneralizedEigenvalue(kb, reference));
  for (std::size_t i = 0; i < modes.size(); ++i) {
    if (i > 0) {
      EXPECT_GE(modes[i].lambda, modes[i - 1].lambda);
    }
    const Vector v = reference.Gather(modes[i].shape);
    const Vector residual = model.Multiply(v) - modes[i].lambda * reference.Multiply(v);
    EXPECT_LT(residual.norm(), 1e-6 * model.Multiply(v).norm()) << i;
    EXPECT_NEAR(modes[i].shape.squaredNorm(), v.squaredNorm(), 1e-12 * v.squaredNorm());
  }
  EXPECT_TRUE(SoftModes(kb, reference, modes[0].lambda * 0.999, 3).empty());
}

// Every probe's error, the tool loads' solved through their base support's factor (as the
// certificate solves them) or each with a factorisation of its own, agree to the solves'
// round-off, for the model and the baseline; no probe is left out.
TEST(ProbeErrors, ToolLoadsSolvedThroughTheirBaseGiveTheirOwnFactorisationsErrors) {
  const Problem problem(examples::Make("fem-kidney-2d"));
  const SparseMatrix kref = ReferenceRestStiffness(problem);
  const ProbeBank bank = MakeProbeBanks(problem, kref, ProbeOptions{}).fit;
  std::vector<double> prior = *BaselineGeneWeights(problem);
  const std::vector<bool> every(bank.probes.size(), true);
  int tools = 0;
  for (const Probe& probe : bank.probes)
    tools += bank.supports[static_cast<std::size_t>(probe.support)].tool();
  ASSERT_GT(tools, 10);
  for (int model = 0; model < 2; ++model) {
    if (model == 1)
      for (std::size_t g = 0; g < prior.size(); ++g)
        prior[g] *= 1.0 + 0.5 * std::sin(3.0 * static_cast<double>(g));
    const SparseMatrix k = SpringRestStiffness(problem, prior);
    const std::vector<double> own = ProbeErrorsFor(bank, k, every);
    const std::vector<double> through =
        ProbeErrorsFor(bank, k, every, nullptr, {}, ToolSolves::kThroughBase);
    ASSERT_EQ(own.size(), through.size());
    for (std::size_t p = 0; p < own.size(); ++p) {
      ASSERT_TRUE(std::isfinite(own[p])) << p;
      EXPECT_NEAR(through[p], own[p], 1e-9 * own[p]) << "probe " << p;
    }
  }
}

}  // namespace
}  // namespace springfit::response
