// A support's factorised system (engine/problem/support_system.h): many right-hand sides in
// one pass give each one's own solve; a tool load's system solves through its base's factor as
// a factorisation of its own would.
#include <gtest/gtest.h>

#include "engine/probe_fit/probe_bank.h"
#include "engine/problem/rest_stiffness.h"
#include "engine/problem/support_system.h"
#include "io/example_catalog.h"

namespace springfit::response {
namespace {

// Many right-hand sides solved in one pass over the factor (blocked_triangular_solve.h) give
// each one's own solve, bit for bit: random columns, a zero one, and one whose leading entries
// are zero (the forward solve skips zero entries).
TEST(SupportSystem, ManyRightHandSidesGiveEachOnesOwnSolveBitForBit) {
  const Problem problem(examples::Make("fem-kidney-2d"));
  const SparseMatrix kref = ReferenceRestStiffness(problem);
  const ProbeBank bank = MakeProbeBanks(problem, kref, ProbeOptions{}).fit;
  SupportSystem system(2, bank.supports[0].constrained);
  ASSERT_TRUE(system.Factorize(kref));
  const int n = system.free_dofs();
  Matrix b = Matrix::Random(n, 19);
  b.col(3).setZero();
  b.col(7).head(n / 2).setZero();
  Matrix together = b;
  system.SolveColumns(together);
  for (Eigen::Index j = 0; j < b.cols(); ++j) {
    Vector alone = b.col(j);
    system.Solve(alone);
    EXPECT_EQ(Vector(together.col(j)), alone) << "column " << j;
  }
  EXPECT_LT((system.Multiply(together.col(0)) - b.col(0)).norm(), 1e-9 * b.col(0).norm());
}

// A tool load's support bordered on its base's factor solves as its own factorisation does, in
// 2D (Eigen's factor) and 3D, for forces and the tool's prescribed displacements; given
// another matrix than its base's, it factorises its own.
TEST(SupportSystem, AToolLoadSolvesThroughItsBasesFactorAsItsOwnFactorisationDoes) {
  for (const char* name : {"fem-kidney-2d", "fem-block-3d"}) {
    const Problem problem(examples::Make(name));
    const int d = problem.dimension();
    const SparseMatrix kref = ReferenceRestStiffness(problem);
    ProbeOptions options;
    options.fit_tools_in_3d = true;  // (the pushes in the fit's bank, where the test sees them)
    const ProbeBank bank = MakeProbeBanks(problem, kref, options).fit;
    int tools = 0;
    for (std::size_t p = 0; p < bank.probes.size() && tools < 3; ++p) {
      const Probe& probe = bank.probes[p];
      const Support& support = bank.supports[static_cast<std::size_t>(probe.support)];
      if (!support.tool()) continue;
      ++tools;
      ASSERT_GE(support.base, 0) << name;
      SupportSystem base(d, bank.supports[static_cast<std::size_t>(support.base)].constrained);
      ASSERT_TRUE(base.Factorize(kref));
      SupportSystem bordered(d, support.constrained, &base), own(d, support.constrained);
      ASSERT_TRUE(bordered.Factorize(kref));
      ASSERT_TRUE(own.Factorize(kref));
      EXPECT_TRUE(bordered.bordered());
      EXPECT_FALSE(own.bordered());
      ASSERT_EQ(bordered.free_dofs(), own.free_dofs());
      // The tool's own load (its nodes at the depth), and forces on the free nodes.
      const Vector expected = own.Displacement(probe.force, probe.prescribed);
      const Vector got = bordered.Displacement(probe.force, probe.prescribed);
      EXPECT_LT((got - expected).norm(), 1e-10 * expected.norm()) << name << " probe " << p;
      EXPECT_LT((got - probe.reference).norm(), 1e-10 * probe.reference.norm()) << name;
      Matrix b = Matrix::Random(own.free_dofs(), 5);
      Matrix x = b, y = b;
      own.SolveColumns(x);
      bordered.SolveColumns(y);
      EXPECT_LT((x - y).norm(), 1e-10 * x.norm()) << name;
      EXPECT_LT((bordered.Multiply(y.col(0)) - b.col(0)).norm(), 1e-9 * b.col(0).norm()) << name;
      // Another matrix than the base's: its own factorisation.
      const SparseMatrix stiffer = 2.0 * kref;
      ASSERT_TRUE(bordered.Factorize(stiffer));
      EXPECT_FALSE(bordered.bordered());
      Vector half = b.col(0);
      bordered.Solve(half);
      EXPECT_LT((2.0 * half - x.col(0)).norm(), 1e-10 * x.col(0).norm()) << name;
    }
    EXPECT_EQ(tools, 3) << name;
  }
}

}  // namespace
}  // namespace springfit::response
