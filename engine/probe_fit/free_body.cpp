#include "engine/probe_fit/free_body.h"

#include <algorithm>

#include <Eigen/QR>

namespace springfit::response {
namespace {

Eigen::Vector3d At3(int d, const Vector& x, int node) {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  p.head(d) = x.segment(d * node, d);
  return p;
}

// Nodes far apart: the farthest from the centroid, the farthest from it, and (3D) the one
// spanning the largest triangle with them.
std::vector<int> FarNodes(int d, const Vector& rest) {
  const int n = static_cast<int>(rest.size()) / d;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (int i = 0; i < n; ++i) centroid += At3(d, rest, i) / n;
  const auto farthest = [&](const auto& score) {
    int best = 0;
    for (int i = 1; i < n; ++i)
      if (score(i) > score(best)) best = i;
    return best;
  };
  const int a = farthest([&](int i) { return (At3(d, rest, i) - centroid).squaredNorm(); });
  const int b = farthest([&](int i) { return (At3(d, rest, i) - At3(d, rest, a)).squaredNorm(); });
  if (d == 2) return {a, b};
  const int c = farthest([&](int i) {
    return (At3(d, rest, b) - At3(d, rest, a)).cross(At3(d, rest, i) - At3(d, rest, a)).norm();
  });
  return {a, b, c};
}

}  // namespace

Matrix RigidMotions(int dimension, const Vector& rest) {
  const int d = dimension;
  const int n = static_cast<int>(rest.size()) / d;
  const int rotations = d == 2 ? 1 : 3;
  Matrix r = Matrix::Zero(d * n, d + rotations);
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (int i = 0; i < n; ++i) centroid += At3(d, rest, i) / n;
  for (int i = 0; i < n; ++i) {
    for (int c = 0; c < d; ++c) r(d * i + c, c) = 1.0;
    const Eigen::Vector3d x = At3(d, rest, i) - centroid;
    for (int k = 0; k < rotations; ++k) {
      const Eigen::Vector3d axis = d == 2 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::Unit(k);
      r.block(d * i, d + k, d, 1) = axis.cross(x).head(d);
    }
  }
  return r;
}

std::vector<bool> DeterminateSupport(int dimension, const Vector& rest) {
  const int d = dimension;
  const Matrix rigid = RigidMotions(d, rest);
  const std::vector<int> nodes = FarNodes(d, rest);
  std::vector<int> dofs;
  for (int node : nodes)
    for (int c = 0; c < d; ++c) dofs.push_back(d * node + c);
  // The rigid motions at those degrees of freedom, one column per degree of freedom: the first
  // columns a pivoted QR picks are the ones that hold every rigid motion best.
  Matrix at(rigid.cols(), static_cast<Eigen::Index>(dofs.size()));
  for (std::size_t j = 0; j < dofs.size(); ++j)
    at.col(static_cast<Eigen::Index>(j)) = rigid.row(dofs[j]).transpose();
  const Eigen::ColPivHouseholderQR<Matrix> qr(at);
  std::vector<bool> held(static_cast<std::size_t>(rest.size()), false);
  for (Eigen::Index k = 0; k < rigid.cols(); ++k)
    held[static_cast<std::size_t>(
        dofs[static_cast<std::size_t>(qr.colsPermutation().indices()[k])])] = true;
  return held;
}

PencilExtremes FreeBodyExtremes(const SparseMatrix& model, const SparseMatrix& reference,
                                int dimension, const Vector& rest, int iterations,
                                Interruption* interruption) {
  const std::vector<bool> held = DeterminateSupport(dimension, rest);
  return PencilExtremesOn(model, reference, SupportSystem::OfDofs(dimension, held),
                          SupportSystem::OfDofs(dimension, held), iterations, interruption);
}

}  // namespace springfit::response
