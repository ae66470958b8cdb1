// The rank of a spring model's rigidity matrix: how many independent motions of the free nodes
// stretch no spring to first order (mechanism modes).
//
// The rest stiffness is K = R^T diag(k) R, R the rigidity matrix (one row per spring, its unit
// direction on its two nodes' coordinates), so K's null space is R's whatever the positive
// stiffness. Deciding the rank on R rather than on K doubles the digits that decide it: K's
// small eigenvalues are R's small singular values squared, and an LDLT of K blurs everything
// below about 1e-16 of its largest eigenvalue into round-off, where a QR of R resolves singular
// values down to about 1e-16 of its largest. A 1-by-3.9e-7 strip of cells (relative lateral
// stiffness 1e-13, eigenvalues of K from 1e-16 up) is rigid, and R says so; K cannot tell.
//
// The QR is SuiteSparseQR's (rank by Heath's method: a column whose remaining norm is below
// the tolerance is dead), on R with its columns scaled to unit norm, which makes the tolerance
// unit-free. Used only where the cheap LDLT of K has found eigenvalues near zero
// (EquilibriumSolver::RestStabilityOf).
#pragma once

#include "engine/api/model.h"
#include "engine/model/springs.h"

namespace springfit {

// The number of singular values of the column-scaled rigidity matrix of `springs` (their
// stiffness ignored) on the free nodes' coordinates at or below `tolerance`, a coordinate with
// no spring counted as one. 0 < tolerance < 1. `suspected`: how many the caller expects at
// most (the stiffness matrix's near-zero eigenvalues); a sparse QR that finds fewer is
// checked by a dense SVD for up to 600 unknowns (Heath's rank can come out too high).
int RigidityRankDeficiency(const SpringGeometry& geometry, const FreeNodes& free,
                           const ActiveSprings& springs, double tolerance, int suspected);

}  // namespace springfit
