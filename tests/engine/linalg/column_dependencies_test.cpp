// The dependencies among a sparse matrix's columns (engine/linalg/column_dependencies.h): exact on
// a built matrix, and on a real force balance where Heath's sparse rank alone misses some.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "engine/linalg/column_dependencies.h"
#include "engine/linalg/sparse_columns.h"
#include "engine/problem/force_balance.h"
#include "io/example_catalog.h"

namespace springfit {
namespace {

SparseMatrix UnitColumns(const SparseMatrix& a) {
  SparseMatrix out = a;
  for (Eigen::Index j = 0; j < out.cols(); ++j) out.col(j) /= out.col(j).norm();
  return out;
}

// |a_j - sum_b c_b a_b| for a circuit.
double CircuitResidual(const SparseMatrix& a, const ColumnDependencies::Circuit& circuit) {
  Vector r = Vector(a.col(circuit.column));
  for (const auto& [b, c] : circuit.basis) r -= c * Vector(a.col(b));
  return r.norm();
}

// 12 rows, 10 columns: 7 independent random-ish columns, then col 7 = col 0 + 2 col 3,
// col 8 = col 1 - col 2, col 9 = col 7 + col 5 (so 0, 3, 5 share its circuit).
SparseMatrix BuiltMatrix() {
  Matrix dense = Matrix::Zero(12, 10);
  for (int j = 0; j < 7; ++j)
    for (int i = 0; i < 12; ++i)
      if ((i * 7 + j * 3) % 4 != 0) dense(i, j) = std::sin(1.0 + i + 13.0 * j);
  dense.col(7) = dense.col(0) + 2.0 * dense.col(3);
  dense.col(8) = dense.col(1) - dense.col(2);
  dense.col(9) = dense.col(7) + dense.col(5);
  return UnitColumns(dense.sparseView());
}

TEST(ColumnDependencies, FindsTheBuiltDependenciesAndTheirCircuits) {
  const SparseMatrix a = BuiltMatrix();
  const ColumnDependencies found = FindColumnDependencies(a);
  ASSERT_TRUE(found.analysed) << found.not_analysed;
  EXPECT_EQ(found.rank, 7);
  ASSERT_EQ(found.circuits.size(), 3u);
  std::set<int> involved;
  for (const ColumnDependencies::Circuit& circuit : found.circuits) {
    EXPECT_LE(CircuitResidual(a, circuit), 1e-12);
    involved.insert(circuit.column);
    for (const auto& [b, c] : circuit.basis) involved.insert(b);
  }
  // Columns 4 and 6 are in no dependency, whatever basis the QR chose.
  EXPECT_EQ(involved, (std::set<int>{0, 1, 2, 3, 5, 7, 8, 9}));
}

// fem-kidney-2d-fine's force balance over its 2,853 genes has 12 singular values below 1e-15
// and the next at 3.7e-5 (NumPy's SVD): 12 dependencies among 386 genes. Heath's rank with
// COLAMD's ordering finds 10 of them; the confirmation finds the other two. Both orderings give
// the same dependent columns.
TEST(ColumnDependencies, HeathsMissedDependenciesAreFoundWhateverTheOrdering) {
  const Problem problem = Problem::Build(examples::Make("fem-kidney-2d-fine"));
  const SparseMatrix a = UnitColumns(AssembleForceBalance(problem).a);
  ASSERT_EQ(a.cols(), 2853);
  std::set<int> involved_first;
  for (const auto ordering :
       {ColumnDependencyOptions::Ordering::kMetis, ColumnDependencyOptions::Ordering::kColamd}) {
    ColumnDependencyOptions options;
    options.ordering = ordering;
    const ColumnDependencies found = FindColumnDependencies(a, options);
    ASSERT_TRUE(found.analysed) << found.not_analysed;
    EXPECT_EQ(found.rank, 2841);
    ASSERT_EQ(found.circuits.size(), 12u);
    std::set<int> involved;
    for (const ColumnDependencies::Circuit& circuit : found.circuits) {
      // Up to the coefficients dropped below circuit_tolerance (1e-8 of the largest; on an
      // ill-conditioned basis the largest reaches 2e5).
      double largest = 1.0;
      for (const auto& [b, c] : circuit.basis) largest = std::max(largest, std::abs(c));
      EXPECT_LE(CircuitResidual(a, circuit), 1e-7 * largest);
      involved.insert(circuit.column);
      for (const auto& [b, c] : circuit.basis) involved.insert(b);
    }
    EXPECT_EQ(involved.size(), 386u);
    if (involved_first.empty()) involved_first = involved;
    EXPECT_EQ(involved, involved_first);
  }
  // Without the repairs COLAMD's rank is not confirmed, and nothing is claimed.
  ColumnDependencyOptions unrepaired;
  unrepaired.ordering = ColumnDependencyOptions::Ordering::kColamd;
  unrepaired.max_repairs = 0;
  const ColumnDependencies claimed = FindColumnDependencies(a, unrepaired);
  EXPECT_FALSE(claimed.analysed);
  EXPECT_TRUE(claimed.circuits.empty());
  EXPECT_NE(claimed.not_analysed.find("the sparse QR's rank 2843 is not confirmed"),
            std::string::npos)
      << claimed.not_analysed;
}

TEST(ColumnDependencies, TheTraceWorkIsBoundedBeforeItStarts) {
  ColumnDependencyOptions options;
  options.max_trace_work = 1.0;
  const ColumnDependencies found = FindColumnDependencies(BuiltMatrix(), options);
  EXPECT_FALSE(found.analysed);
  EXPECT_TRUE(found.circuits.empty());
  EXPECT_EQ(found.not_analysed, "3 dependencies among 10 columns are too many to trace");
}

}  // namespace
}  // namespace springfit
