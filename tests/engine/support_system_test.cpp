// A support's factorised system (engine/probe_fit/support_system.h): many right-hand sides in
// one pass give each one's own solve.
#include <gtest/gtest.h>

#include "engine/probe_fit/probe_bank.h"
#include "engine/probe_fit/rest_stiffness.h"
#include "engine/probe_fit/support_system.h"
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

}  // namespace
}  // namespace springfit::response
