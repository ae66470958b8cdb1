// The one objective every matrix-free probe fit descends (docs/ARCHITECTURE.md, "The fitting
// core"): a spring model's weighted displacement error under probe loads and its Gauss-Newton
// operators in the stiffness, from sparse solves alone.
//
// With x the scaled stiffness (k = S x, ProbeObjective), the springs' energy
// sum_e 1/2 k_e (L_e - l_e)^2 and an equilibrium u_p of probe p, the internal force is
// sum_e k_e (L_e - l_e) dL_e/du, so differentiating the equilibrium in k gives
//   du_p/dk_e = -H_p^-1 g_e (L_e - l_e),      J_p = -sqrt(w_p) H_p^-1 G_p diag(s_p) S,
// with H_p the tangent stiffness at u_p on the free degrees of freedom, G_p's column e the
// derivative of spring e's length dL_e/du there, and s_p the stretches L_e - l_e. Two
// linearisations fill in those terms:
//  - at rest (linearized_response.h): H the rest stiffness, G the rest directions and s the
//    stretches' linearisation, so one factorisation per support serves all its probes;
//  - at the nonlinear equilibria (nonlinear_response.h): H the exact tangent at each probe's
//    equilibrium and G its springs' current directions, one factorisation per probe and
//    amplitude (the adjoint of the simulator's own spring law).
// Everything else is this class's algebra, shared: r = sqrt(w)(u - u_ref), J^T r (one solve per
// probe), J^T J v (two), and a Hutchinson estimate of J^T J's diagonal. A part is one factorised
// H with the probes solved on it; parts run in parallel on the pool and their sums run in part
// order, so nothing depends on the threads.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "engine/probe_fit/gene_springs.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/runtime/interruption.h"
#include "engine/runtime/worker_pool.h"

namespace springfit::response {

class SpringSensitivities {
 public:
  virtual ~SpringSensitivities() = default;
  SpringSensitivities(const SpringSensitivities&) = delete;
  SpringSensitivities& operator=(const SpringSensitivities&) = delete;

  // Linearises at per-gene `weights`: the model solved for every fitted probe and its systems
  // factorised. False when the model has no (stable) equilibrium for some probe: a mechanism on
  // a support, an equilibrium Newton does not reach, or a tangent that is not positive definite
  // (a fold). Throws Interrupted when stopped.
  virtual bool At(const std::vector<double>& weights) = 0;
  // The rest model of the last successful At() factorised on each support it holds one for
  // (the rest linearisation's), for the judgements of that model; none by default.
  virtual FactorizedOn Factorized() const { return {}; }
  // Releases what the operators (Gradient, NormalProduct, NormalDiagonal) need beyond the
  // residuals, which the next operator call rebuilds with the same bits: a caller that reads
  // only values for a while (the line search's trials, GaussNewtonPoint::Idle). Nothing by
  // default.
  virtual void Idle() {}

  // sum_p |r_p|^2.
  double ResidualNorm2() const;
  // The residuals r_p stacked in part order, then in each part's probe order.
  Vector Residuals() const;
  // J^T r, per gene.
  Vector Gradient() const;
  // J^T J v, per gene.
  Vector NormalProduct(const Vector& v) const;
  // An estimate of J^T J's diagonal, S_e^2 sum_p w_p s_pe^2 |H^-1 g_e|^2, with |H^-1 g_e|^2
  // from `samples` random sign vectors z per part (Hutchinson: E[(g_e^T H^-1 z)^2] =
  // |H^-1 g_e|^2), seeded by `seed` and the part's key.
  Vector NormalDiagonal(int samples, std::uint64_t seed) const;

 protected:
  SpringSensitivities(const Vector& scale, int genes, Interruption* interruption, WorkerPool* pool);

  struct Part {
    std::uint64_t key = 0;              // salts the diagonal's random vectors
    std::vector<SpringColumn> columns;  // per gene: g_e on the part's free degrees of freedom
    Matrix residual;                    // free x probes: sqrt(w_p) (u_p - u_ref,p)
    Matrix elongation;                  // genes x probes: sqrt(w_p) s_p
  };
  // B <- H^-1 B for part `part` (one call, any number of columns).
  virtual void Solve(std::size_t part, Matrix& b) const = 0;

  // f(part i) for every part, in parallel on the pool; throws Interrupted when stopped.
  void Run(const std::function<void(std::size_t)>& f) const;
  // B <- H^-1 B in chunks between stop checks.
  void SolveColumns(std::size_t part, Matrix& b) const;

  Interruption* interruption_;
  WorkerPool* pool_;
  std::vector<Part> parts_;

 private:
  // Per gene e: S_e sum_p sqrt(w_p) s_pe g_e^T z_p.
  Vector ColumnProducts(const Part& part, const Matrix& z) const;
  // The sum over the parts of a per-gene vector each computes, in part order.
  Vector Sum(const std::function<Vector(std::size_t)>& f) const;

  Vector scale_;
  int genes_;
};

}  // namespace springfit::response
