// Eigen type aliases used throughout the engine, in one place.
//
// Positions and displacements of a scene with n nodes in dimension d are stored as one flat
// vector of length d*n, node-major: node i occupies entries [d*i, d*i + d).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SparseCore>

namespace springfit {

using Vector = Eigen::VectorXd;
using Matrix = Eigen::MatrixXd;
using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor>;

template <int D>
using VecD = Eigen::Matrix<double, D, 1>;
template <int D>
using MatD = Eigen::Matrix<double, D, D>;

}  // namespace springfit
