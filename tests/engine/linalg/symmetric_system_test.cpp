// The factorisation behind the equilibrium solver, on matrices whose answers are known: the
// banded path's fallback to a pivoted LDLT where its Cholesky fails, and the empty system.
#include "engine/linalg/symmetric_system.h"

#include "engine/linalg/supernodal_cholesky.h"

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

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
  for (auto backend : {SymmetricSystem::Backend::kBanded, SymmetricSystem::Backend::kSparse,
                       SymmetricSystem::Backend::kSupernodal}) {
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
    // The count is of eigenvalues below the tolerance, not of pivots: shifted past the
    // smallest positive eigenvalue, it counts that one too.
    const double second = eigen.eigenvalues()[1];
    ASSERT_GT(second, 0.0);
    EXPECT_EQ(system.CountEigenvaluesBelow(0.0, second * 1.001), 2);
    EXPECT_EQ(system.CountEigenvaluesBelow(0.0, second * 0.999), 1);
    // Solved with the indefinite factorisation whatever the backend (an unstable
    // equilibrium's resolution needs H^-1 r): A x = b to round-off.
    const SymmetricSystem::Factorization g = system.FactorizeIndefinite(0.0);
    EXPECT_LT(g.min_pivot, 0.0);
    EXPECT_NE(g.min_pivot, 0.0);
    const Vector b = Vector::LinSpaced(a.rows(), 1.0, 2.0);
    Vector x = b;
    system.Solve(x);
    EXPECT_LT((a * x - b).norm(), 1e-12 * b.norm());
  }
}

// The graph Laplacian of an n x n grid (5-point stencil) plus `shift` on the diagonal: positive
// definite for shift > 0, one null vector (the constant) for shift 0.
SymmetricSystem GridLaplacian(int n, double shift, SymmetricSystem::Backend backend,
                              Matrix* dense) {
  const int size = n * n;
  std::vector<std::pair<int, int>> lower;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const int i = y * n + x;
      if (x > 0) lower.emplace_back(i, i - 1);
      if (y > 0) lower.emplace_back(i, i - n);
    }
  }
  SymmetricSystem system(size, lower, backend);
  system.SetZero();
  *dense = Matrix::Zero(size, size);
  for (const auto& [r, c] : lower) {
    system.values()[system.Slot(r, c)] = -1.0;
    system.values()[system.Slot(r, r)] += 1.0;
    system.values()[system.Slot(c, c)] += 1.0;
    (*dense)(r, c) = (*dense)(c, r) = -1.0;
    (*dense)(r, r) += 1.0;
    (*dense)(c, c) += 1.0;
  }
  for (int i = 0; i < size; ++i) {
    system.values()[system.Slot(i, i)] += shift;
    (*dense)(i, i) += shift;
  }
  return system;
}

TEST(SymmetricSystem, TheThreeBackendsAgreeOnDefiniteAndSingularMatrices) {
  for (auto backend : {SymmetricSystem::Backend::kBanded, SymmetricSystem::Backend::kSparse,
                       SymmetricSystem::Backend::kSupernodal}) {
    Matrix a;
    SymmetricSystem system = GridLaplacian(9, 0.01, backend, &a);
    const SymmetricSystem::Factorization f = system.Factorize(0.0, 1e-10, true);
    EXPECT_TRUE(f.positive_definite);
    EXPECT_EQ(f.small_pivots, 0);
    const Vector x = Vector::LinSpaced(81, -1.0, 2.0);
    Vector b = a * x;
    system.Solve(b);
    EXPECT_LE((b - x).norm(), 1e-10 * x.norm()) << static_cast<int>(backend);
    // A copy analyses the pattern anew and factorises alike.
    SymmetricSystem copy = system;
    EXPECT_TRUE(copy.Factorize(0.0, 1e-10, true).positive_definite);
    Vector b2 = a * x;
    copy.Solve(b2);
    EXPECT_LE((b2 - x).norm(), 1e-10 * x.norm()) << static_cast<int>(backend);
    // Without the shift the Laplacian has one null vector: one small pivot under a tiny shift.
    SymmetricSystem singular = GridLaplacian(9, 0.0, backend, &a);
    const SymmetricSystem::Factorization s = singular.Factorize(1e-13, 1e-10, true);
    EXPECT_EQ(s.small_pivots, 1) << static_cast<int>(backend);
    EXPECT_FALSE(s.positive_definite);
  }
}

// The bytes a system holds (memory estimates before a large solve: the nonlinear stage's bound)
// grow with its factor's fill, which the analysis knows before any factorisation: a dense
// pattern's factor has n (n - 1) / 2 entries below the diagonal, a path's n - 1. Each backend's
// estimate covers its factor, and a factorisation allocates nothing the estimate missed.
TEST(SymmetricSystem, ItsBytesCountTheFactorsFillBeforeAnyFactorisation) {
  const int n = 300;
  std::vector<std::pair<int, int>> dense, path;
  for (int i = 1; i < n; ++i) {
    path.emplace_back(i, i - 1);
    for (int j = 0; j < i; ++j) dense.emplace_back(i, j);
  }
  const double below = 0.5 * n * (n - 1.0);
  for (auto backend : {SymmetricSystem::Backend::kSparse, SymmetricSystem::Backend::kSupernodal}) {
    const SymmetricSystem full(n, dense, backend);
    const SymmetricSystem chain(n, path, backend);
    // (the matrix and its scaled copy, 12 bytes per entry each, and the factor, 8 at least)
    EXPECT_GE(full.Bytes(), (2.0 * 12.0 + 8.0) * below) << static_cast<int>(backend);
    EXPECT_LT(chain.Bytes(), 0.05 * full.Bytes()) << static_cast<int>(backend);
  }
}

// The supernodal factor solved by springfit's own loops over its columns (SolveColumns) gives
// CHOLMOD's solve to round-off, for many right-hand sides at once: a 3D grid Laplacian, whose
// supernodes are wide enough to have dense blocks below their diagonal.
TEST(SupernodalCholesky, ItsBlockedSolveMatchesCholmodsSolve) {
  const int side = 12, n = side * side * side;
  std::vector<Eigen::Triplet<double>> t;
  const auto at = [side](int i, int j, int k) { return (k * side + j) * side + i; };
  for (int k = 0; k < side; ++k)
    for (int j = 0; j < side; ++j)
      for (int i = 0; i < side; ++i) {
        const int a = at(i, j, k);
        t.emplace_back(a, a, 6.01);
        if (i + 1 < side) t.emplace_back(at(i + 1, j, k), a, -1.0);
        if (j + 1 < side) t.emplace_back(at(i, j + 1, k), a, -1.0);
        if (k + 1 < side) t.emplace_back(at(i, j, k + 1), a, -1.0);
      }
  Eigen::SparseMatrix<double> lower(n, n);
  lower.setFromTriplets(t.begin(), t.end());
  lower.makeCompressed();
  SupernodalCholesky cholesky(n, lower.outerIndexPtr(), lower.innerIndexPtr());
  ASSERT_TRUE(cholesky.Factorize(lower.outerIndexPtr(), lower.innerIndexPtr(), lower.valuePtr()));
  const Matrix x = Matrix::Random(n, 21);
  const Matrix b = lower.selfadjointView<Eigen::Lower>() * x;
  Matrix ours = b, cholmods = b;
  cholesky.SolveColumns(ours);
  cholesky.Solve(cholmods);
  EXPECT_LE((ours - cholmods).norm(), 1e-12 * cholmods.norm());
  EXPECT_LE((ours - x).norm(), 1e-10 * x.norm());
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
