// The free-body pencil: the model's stiffness against the reference's on the body held by no
// support at all, modulo its rigid motions (docs/ARCHITECTURE.md, "Any support").
//
// Displacements that differ by a rigid motion store the same energy in both models, so the
// Rayleigh quotient u^T K_model u / u^T K_ref u is a function of u modulo rigid motions. A
// support restricts u to a subspace, so every supported pencil's eigenvalues lie within the
// free body's extremes: if those are [lambda_min, lambda_max], every load on every support is
// reproduced within max(1/lambda_min - 1, 1 - 1/lambda_max) in the reference's energy norm.
// The quotient modulo rigid motions is computed on a statically determinate support, which holds
// exactly as many single degrees of freedom as there are rigid motions (3 in 2D, 6 in 3D) and
// removes them all: its free displacements are the body's displacements modulo rigid motions,
// one for one.
#pragma once

#include <vector>

#include "engine/api/problem.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/runtime/interruption.h"

namespace springfit::response {

// The rigid motions of the body at rest, flat d*n each: d translations, then the rotations
// about its centroid (1 in 2D, 3 in 3D).
Matrix RigidMotions(int dimension, const Vector& rest);

// Per flat degree of freedom, whether the statically determinate support holds it: three nodes
// far apart (two in 2D), the degrees of freedom among theirs on which the rigid motions are
// best conditioned (column-pivoted QR).
std::vector<bool> DeterminateSupport(int dimension, const Vector& rest);

// The extremes of the free-body pencil (model, reference), both d*n rest stiffnesses;
// lambda_min 0 when the model has an internal mechanism. Lanczos as
// GeneralizedEigenvalueExtremes; `interruption` checked at every step.
PencilExtremes FreeBodyExtremes(const SparseMatrix& model, const SparseMatrix& reference,
                                int dimension, const Vector& rest,
                                int iterations = kLanczosIterations,
                                Interruption* interruption = nullptr);

}  // namespace springfit::response
