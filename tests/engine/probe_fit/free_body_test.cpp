// The free-body pencil (engine/probe_fit/free_body.h): its extremes against a dense solve of the
// pencil on the complement of the rigid motions, and their range containing every supported
// pencil's.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include "engine/examples/catalog.h"
#include "engine/probe_fit/free_body.h"
#include "engine/probe_fit/generalization.h"
#include "engine/problem/baseline_evaluation.h"
#include "engine/problem/rest_stiffness.h"
#include "io/example_catalog.h"

namespace springfit::response {
namespace {

// The extremes of (K_model, K_ref) on displacements orthogonal to the rigid motions, densely.
PencilExtremes DenseFreeBody(const Matrix& model, const Matrix& reference, const Matrix& rigid) {
  const Eigen::HouseholderQR<Matrix> qr(rigid);
  const Matrix q = qr.householderQ();
  const Matrix complement = q.rightCols(q.cols() - rigid.cols());
  const Matrix a = complement.transpose() * model * complement;
  const Matrix b = complement.transpose() * reference * complement;
  const Eigen::GeneralizedSelfAdjointEigenSolver<Matrix> eig(a, b);
  return {eig.eigenvalues().minCoeff(), eig.eigenvalues().maxCoeff()};
}

TEST(FreeBody, TheDeterminateSupportHoldsEveryRigidMotionAndNothingElse) {
  for (const char* name : {"fem-plate-5x5", "fem-block-3d"}) {
    const Problem problem(examples::Make(name));
    const int d = problem.dimension();
    const std::vector<bool> held = DeterminateSupport(d, problem.scene().rest);
    EXPECT_EQ(std::count(held.begin(), held.end(), true), d == 2 ? 3 : 6) << name;
    // The rigid motions at the held degrees of freedom: a square, non-singular matrix.
    const Matrix rigid = RigidMotions(d, problem.scene().rest);
    Matrix at(0, rigid.cols());
    for (std::size_t dof = 0; dof < held.size(); ++dof) {
      if (!held[dof]) continue;
      at.conservativeResize(at.rows() + 1, Eigen::NoChange);
      at.row(at.rows() - 1) = rigid.row(static_cast<Eigen::Index>(dof));
    }
    EXPECT_GT(std::abs(at.determinant()),
              1e-6 * std::pow(at.norm(), static_cast<double>(at.rows())))
        << name;
    // They are the rigid motions: the reference stores no energy in any of them.
    const SparseMatrix reference = ReferenceRestStiffness(problem);
    const Matrix energy = Matrix(reference) * rigid;
    EXPECT_LT(energy.norm(), 1e-9 * Matrix(reference).norm() * rigid.norm()) << name;
  }
}

TEST(FreeBody, ExtremesMatchADenseSolveAndContainEverySupportsPencil) {
  const Problem problem(examples::Make("fem-plate-5x5"));
  const SparseMatrix reference = ReferenceRestStiffness(problem);
  std::vector<double> model = *BaselineGeneWeights(problem);
  for (std::size_t g = 0; g < model.size(); g += 3) model[g] *= 2.5;  // a model unlike the FEM
  const SparseMatrix k_model = SpringRestStiffness(problem, model);
  const Vector& rest = problem.scene().rest;
  const PencilExtremes lanczos = FreeBodyExtremes(k_model, reference, 2, rest);
  const PencilExtremes dense =
      DenseFreeBody(Matrix(k_model), Matrix(reference), RigidMotions(2, rest));
  EXPECT_NEAR(lanczos.lambda_min, dense.lambda_min, 1e-8 * dense.lambda_max);
  EXPECT_NEAR(lanczos.lambda_max, dense.lambda_max, 1e-8 * dense.lambda_max);
  // Every support's pencil lies within the free body's.
  for (const FreeNodes& free : problem.free_sets()) {
    std::vector<bool> constrained(free.free_index.size());
    for (std::size_t node = 0; node < constrained.size(); ++node)
      constrained[node] = free.free_index[node] < 0;
    const PencilExtremes held = GeneralizedEigenvalueExtremes(k_model, reference, constrained, 2);
    EXPECT_GE(held.lambda_min, lanczos.lambda_min * (1.0 - 1e-9));
    EXPECT_LE(held.lambda_max, lanczos.lambda_max * (1.0 + 1e-9));
  }
  EXPECT_GE(lanczos.Bound(), 0.0);
}

// A scaled scene gives the same pencil: both stiffnesses scale alike.
TEST(FreeBody, ThePencilIsScaleInvariant) {
  const Problem problem(examples::Make("fem-plate-5x5"));
  const SparseMatrix reference = ReferenceRestStiffness(problem);
  const std::vector<double> model = *BaselineGeneWeights(problem);
  const SparseMatrix k_model = SpringRestStiffness(problem, model);
  const PencilExtremes one = FreeBodyExtremes(k_model, reference, 2, problem.scene().rest);
  const SparseMatrix scaled_model = 1e6 * k_model, scaled_reference = 1e6 * reference;
  const PencilExtremes scaled =
      FreeBodyExtremes(scaled_model, scaled_reference, 2, 1e-3 * problem.scene().rest);
  EXPECT_NEAR(scaled.lambda_min, one.lambda_min, 1e-9 * one.lambda_min);
  EXPECT_NEAR(scaled.lambda_max, one.lambda_max, 1e-9 * one.lambda_max);
}

}  // namespace
}  // namespace springfit::response
