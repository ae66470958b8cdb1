// The probe fit's one driver (response_fit.h, step 2), without a Gram matrix: a Gram matrix in
// the genes takes m^2 doubles and m^3 / 3 per Newton step, which rules it out on meshes (a 3D
// mesh of a thousand nodes has six thousand springs). It uses only sparse solves with each
// support's factorisation, so its memory grows with the mesh and the probes, not with the
// square of the springs.
//
// Projected Gauss-Newton on the exact error (the rest-linear responses) over the fitted probes,
// started from the prior (the closed-form baseline), in the scaled variables x = k / scale:
//   minimise  Phi(x) = sum_p w_p |u_p(k) - u_ref,p|^2 + (lambda / m) |x - x_prior|^2 + P(x),
//   x >= 0, P the held modes' penalty (mode_cuts.h, its half gradient and Hessian added below).
// With u_p = C(k) f_p, C the model's compliance on the probe's support, the Jacobian is
// J_p = -sqrt(w_p) C G diag(delta_p) S (G the springs' force columns, delta_p the model's
// elongations, S the scales). Each step:
//   1. the model factorised on every fitted support, its displacements (one solve per probe);
//   2. the gradient g = J^T r + (lambda / m)(x - x_prior) (one solve per probe);
//   3. the Gauss-Newton system (J^T J + lambda / m) d = -g on the springs not held at their
//      bound (x_e = 0 with g_e > 0), by conjugate gradients preconditioned with J^T J's
//      diagonal (estimated from `diagonal_samples` random vectors per support: |C g_e|^2 by
//      Hutchinson's estimator); each product J^T J v is two solves per probe;
//   4. the projected step max(x + t d, 0), t halved until Phi falls (Bertsekas' projected arc).
// The Tikhonov strengths are a continuation (strongest first, `steps_per_strength` steps each,
// ended after `continuation_patience` strengths in a row that do no better):
// every accepted iterate is judged on the choosing probes and the best is returned, preferring
// one that holds every mode (min_lambda). Springs the fit drives to 0,
// or to dust, leave the model. Every mode a judged model leaves below the held target gives a
// cut whose penalty joins Phi (mode_cuts.h). With a spring budget, the least salient springs of
// the chosen model (1/2 x_e^2 (J^T J)_ee) are removed, a tenth at a time down to it, each
// removal followed by a strength's steps on the springs left.
// The work per step is solves, in parallel over the supports on the pool; the sums run in
// support order, so the result does not depend on the threads.
#pragma once

#include <functional>
#include <memory>

#include "engine/probe_fit/nonlinear_response.h"
#include "engine/probe_fit/probe_objective.h"
#include "engine/probe_fit/response_fit.h"

namespace springfit::response {

ResponseFitResult FitResponseMatrixFree(const Problem& problem, const ProbeBank& bank,
                                        const SparseMatrix& reference_stiffness,
                                        const std::vector<double>& prior,
                                        const ResponseFitOptions& options,
                                        Interruption* interruption,
                                        const ResponseProgress& progress, WorkerPool* pool);

// The nonlinear stage (docs/ARCHITECTURE.md, "The nonlinear fit"): the same driver from the
// rest-linear fit's model `start`, on the nonlinear objective (nonlinear_response.h) with the
// Tikhonov pull toward `start` at the strengths of `nonlinear.regularizations`, springs absent
// from `start` kept out; every iterate, `start` first, is chosen among on the choosing probes
// solved at the amplitudes. So the returned model is never worse there than `start`.
// `baseline` (per gene), when given, is judged on the same choosing cases.
NonlinearFitResult FitNonlinearResponse(
    const Problem& problem, const ProbeBank& bank, const SparseMatrix& reference_stiffness,
    const std::vector<double>& start, const ResponseFitOptions& options,
    const NonlinearFitOptions& nonlinear, const std::vector<double>* baseline,
    Interruption* interruption, const ResponseProgress& progress, WorkerPool* pool);

}  // namespace springfit::response
