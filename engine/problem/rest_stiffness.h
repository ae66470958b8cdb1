// Stiffness matrices at rest: the linear response of the reference (an FEM model's or an MSS's)
// and of a spring model, as sparse matrices on every degree of freedom (flat d*n, node-major).
//
// At rest a spring of stiffness k and unit direction n contributes k n n^T to its nodes' blocks
// (+ on the diagonal blocks, - on the off-diagonal ones): the linearised spring
// (springs.h, SpringState::Linearised). An FEM element contributes
//   K_ab(i, k) = V0 sum_JL A_iJkL G_aJ G_bL       (fem_model.h)
// with A the material's tangent at F = I, the same for the linear, St. Venant-Kirchhoff and
// neo-Hookean laws (material_law.h: they agree to first order). So these matrices describe the
// small-load limit of every reference and model, which is what the probe fit matches
// (docs/ARCHITECTURE.md, "The probe fit").
#pragma once

#include <vector>

#include <Eigen/SparseCore>

#include "engine/api/problem.h"

namespace springfit {

// The reference's rest stiffness: the FEM model's, or the reference springs' with their
// stiffness. Precondition: the reference is FEM or MSS (not positions).
SparseMatrix ReferenceRestStiffness(const Problem& problem);

// The rest stiffness of springs over the problem's candidates: `weights` per gene (0 = absent),
// and the candidates no load case sees at Problem::unidentifiable_stiffness (part of every
// model: they hold the body under the probe bank's other supports as under a simulator's).
SparseMatrix SpringRestStiffness(const Problem& problem, const std::vector<double>& weights);

// The same for explicit springs over the scene's nodes.
SparseMatrix SpringRestStiffness(int dimension, const Vector& rest,
                                 const std::vector<NodePair>& springs,
                                 const std::vector<double>& stiffness);

}  // namespace springfit
