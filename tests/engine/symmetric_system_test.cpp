// The factorisation behind the equilibrium solver, on matrices whose answers are known: the
// banded path's fallback to a pivoted LDLT where its Cholesky fails, and the empty system.
#include "engine/symmetric_system.h"

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

namespace springfit {
namespace {

// A tridiagonal matrix (bandwidth 1) with unit diagonal: the coupling 2 between unknowns 1 and
// 2 makes it indefinite (that 2x2 block has eigenvalues 3 and -1), so the band Cholesky stops at
// unknown 2, after it has overwritten the columns before.
SymmetricSystem Indefinite(SymmetricSystem::Backend backend, Matrix* dense) {
  const int n = 6;
  std::vector<std::pair<int, int>> lower;
  for (int i = 1; i < n; ++i) lower.emplace_back(i, i - 1);
  SymmetricSystem system(n, lower, backend);
  system.SetZero();
  *dense = Matrix::Zero(n, n);
  for (int i = 0; i < n; ++i) {
    system.values()[system.Slot(i, i)] = 1.0;
    (*dense)(i, i) = 1.0;
  }
  const double coupling[] = {0.3, 2.0, 0.3, 0.2, 0.1};
  for (int i = 1; i < n; ++i) {
    system.values()[system.Slot(i, i - 1)] = coupling[i - 1];
    (*dense)(i, i - 1) = (*dense)(i - 1, i) = coupling[i - 1];
  }
  return system;
}

TEST(SymmetricSystem, IndefiniteMatricesAreCountedAndSolvedOnBothBackends) {
  for (auto backend : {SymmetricSystem::Backend::kBanded, SymmetricSystem::Backend::kSparse}) {
    Matrix a;
    SymmetricSystem system = Indefinite(backend, &a);
    EXPECT_EQ(system.ToDense(), a);
    const Eigen::SelfAdjointEigenSolver<Matrix> eigen(a);
    const auto negative = (eigen.eigenvalues().array() < 0.0).count();
    ASSERT_EQ(negative, 1);
    const SymmetricSystem::Factorization f = system.Factorize(0.0, 1e-10, true);
    EXPECT_FALSE(f.positive_definite);
    // Sylvester's law of inertia: as many negative pivots as negative eigenvalues.
    EXPECT_EQ(f.small_pivots, negative);
    EXPECT_LT(f.min_pivot, 0.0);
    // The same factorisation solves the indefinite system.
    const Vector x = Vector::LinSpaced(6, -1.0, 2.0);
    Vector b = a * x;
    system.Solve(b);
    EXPECT_LE((b - x).norm(), 1e-12 * x.norm());
  }
}

TEST(SymmetricSystem, AnEmptySystemIsPositiveDefiniteAndSolvesToNothing) {
  SymmetricSystem system(0, {}, SymmetricSystem::Backend::kBanded);
  const SymmetricSystem::Factorization f = system.Factorize(0.0, 1e-10, true);
  EXPECT_TRUE(f.positive_definite);
  EXPECT_EQ(f.small_pivots, 0);
  Vector b(0);
  system.Solve(b);
  EXPECT_EQ(b.size(), 0);
}

}  // namespace
}  // namespace springfit
