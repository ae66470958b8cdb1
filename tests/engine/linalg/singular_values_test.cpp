// SingularValues (engine/linalg/singular_values.h): LAPACK's values against closed forms, on
// tall, wide, rank-deficient and empty matrices.
#include "engine/linalg/singular_values.h"

#include <cmath>

#include <gtest/gtest.h>

namespace springfit {
namespace {

TEST(SingularValues, AreTheClosedFormsDescending) {
  Matrix a(2, 2);
  a << 3, 0, 4, 5;  // A^T A = [[25, 20], [20, 25]]: eigenvalues 45 and 5
  const Vector s = SingularValues(a);
  ASSERT_EQ(s.size(), 2);
  EXPECT_NEAR(s[0], std::sqrt(45.0), 1e-14 * s[0]);
  EXPECT_NEAR(s[1], std::sqrt(5.0), 1e-14 * s[0]);
  EXPECT_EQ(a(1, 0), 4) << "the input is left as it was";

  Matrix permuted = Matrix::Zero(4, 3);  // tall: a diagonal's absolute values, sorted
  permuted(2, 0) = -1.0;
  permuted(0, 1) = 3.0;
  permuted(3, 2) = 2.0;
  const Vector d = SingularValues(permuted);
  ASSERT_EQ(d.size(), 3);
  EXPECT_NEAR(d[0], 3.0, 1e-15 * 3);
  EXPECT_NEAR(d[1], 2.0, 1e-15 * 3);
  EXPECT_NEAR(d[2], 1.0, 1e-15 * 3);
  EXPECT_EQ(SingularValues(permuted.transpose()), d) << "wide: the same values";
}

TEST(SingularValues, SeeARankDeficiencyAndScaleWithTheMatrix) {
  Matrix a(4, 3);
  a << 1, 2, 3, 4, 5, 9, -1, 0.5, -0.5, 2, -2, 0;  // column 3 = column 1 + column 2
  const Vector s = SingularValues(a);
  ASSERT_EQ(s.size(), 3);
  EXPECT_GT(s[1], 1e-3 * s[0]);
  EXPECT_LT(s[2], 1e-14 * s[0]);
  const Vector scaled = SingularValues(1e-9 * a);
  for (int i = 0; i < 2; ++i) EXPECT_NEAR(scaled[i], 1e-9 * s[i], 1e-14 * 1e-9 * s[0]);
  EXPECT_EQ(SingularValues(Matrix(0, 3)).size(), 0);
}

}  // namespace
}  // namespace springfit
