// Solves with a sparse Cholesky factor for many right-hand sides at once.
//
// Eigen's sparse triangular solve walks the whole factor once per right-hand side: on a 3D
// support (fem-block-3d, 3,000 free degrees of freedom) the factor does not stay in cache, and
// the probe fit's batched solves spent most of their time streaming it (bench/RESULTS.md, "Large
// 3D meshes"). Here the right-hand sides are stored row by row, so one pass over the factor
// updates all of them. Each right-hand side sees the same operations in the same order as in
// Eigen's solve, so the results are the same bits.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace springfit {

// Right-hand sides stored row by row: row i holds every column's entry i.
using RowBlock = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Overwrites b (n x m) with (L L^T)^-1 b. L is lower triangular in compressed columns, every
// column holding its diagonal, in the factor's own (permuted) order: the caller permutes.
void SolveWithCholeskyFactor(const Eigen::SparseMatrix<double>& factor, RowBlock& b);

}  // namespace springfit
