// The identification cost of a topology: how far its equilibria are from the reference's.
//
//   f = sum_k sum_i |X^R_ik - X^M_ik|^2            (Bianchi et al. 2003)
// over load cases k and the nodes i free in case k (constrained nodes match by construction),
// and the unit-free normalised error e = f / sum_k sum_i |u^R_ik|^2, u^R the reference's
// displacements. Scaling all lengths and forces of a scene by s scales f by s^2 and leaves e
// unchanged.
//
// A topology that cannot carry the loads gets no equilibrium and instead a finite, graded
// penalty on e, above every stable topology's error:
//   mechanism (rest stiffness singular):  e = kPenaltyBase * (1 + modes)
//   solver did not converge:              e = kPenaltyBase * 1.5
//   stable but e > kPenaltyBase:          e = kPenaltyBase (as useless as a near-mechanism)
// where `modes` sums the mechanism modes over all load cases: missing one spring scores
// better than missing twenty, so a search is not blind among mostly unstable genomes.
// The penalised cost is f = e * sum |u^R|^2, so cost and error stay proportional.
//
// The cost's vocabulary (Evaluation, CostOptions, CostFunction) is on the surface,
// engine/api/problem.h; this header adds what the engine's rooms use of it.
#pragma once

#include "engine/api/problem.h"

namespace springfit {

// Normalised error of a stable topology can reach this (displacements about 1000 times the
// reference's) before it is capped; mechanisms start at twice it.
inline constexpr double kPenaltyBase = 1e6;

}  // namespace springfit
