// A spring model's response to the fitted probes, linearised in its stiffness at one point: the
// operators of the matrix-free probe fit (matrix_free_fit.h), from sparse solves alone.
//
// With x the scaled stiffness (k = S x, ProbeObjective) and, per fitted probe p on support s,
// u_p = C_s f_p the model's displacement (C_s its compliance there), the weighted residual is
// r_p = sqrt(w_p) (u_p - u_ref,p) on the support's free degrees of freedom and its Jacobian
//   J_p = -sqrt(w_p) C_s G diag(delta_p) S,
// G the springs' force columns and delta_p the elongations under u_p (dK u = G diag(delta) dk).
// So J^T r costs one solve per probe and J^T J v two, batched per support (one factorisation,
// many right-hand sides) and run in parallel over the supports; the sums over supports run in
// support order, so nothing depends on the threads.
#pragma once

#include <cstdint>
#include <vector>

#include "engine/interruption.h"
#include "engine/response/compliance_gram.h"
#include "engine/response/probe_objective.h"
#include "engine/worker_pool.h"

namespace springfit::response {

class LinearizedResponse {
 public:
  // `objective` and `springs` (GeneSpringsOf its problem) must outlive this object.
  LinearizedResponse(const ProbeObjective& objective, const GeneSprings& springs,
                     Interruption* interruption = nullptr, WorkerPool* pool = nullptr);

  // Linearises at per-gene `weights`: the model factorised on every fitted support and solved
  // for every fitted probe. False when some fitted support does not hold it (a mechanism).
  // Throws Interrupted between batches of solves when `interruption` stops it.
  bool At(const std::vector<double>& weights);

  // The model of the last successful At() factorised on every fitted support (null on
  // others), for the judgements of that model (ProbeObjective::SelectError, LambdaMin).
  FactorizedOn Factorized() const;

  // sum_p |r_p|^2 = sum_p w_p |u_p - u_ref,p|^2.
  double ResidualNorm2() const;
  // The residuals r_p stacked in support order, then in the bank's order of the probes.
  Vector Residuals() const;
  // J^T r, per gene.
  Vector Gradient() const;
  // J^T J v, per gene.
  Vector NormalProduct(const Vector& v) const;
  // An estimate of J^T J's diagonal, S_e^2 sum_p w_p delta_pe^2 |C g_e|^2, with |C g_e|^2 from
  // `samples` random sign vectors z per support (Hutchinson: E[(g_e^T C z)^2] = |C g_e|^2),
  // seeded by `seed` and the support.
  Vector NormalDiagonal(int samples, std::uint64_t seed) const;

 private:
  struct Part {
    std::size_t support = 0;
    SupportSystem system;
    std::vector<int> probes;            // the bank's indices of the fitted probes on it
    std::vector<SpringColumn> columns;  // per gene, on the free degrees of freedom
    Matrix residual;                    // free x probes: sqrt(w_p) (u_p - u_ref,p)
    Matrix elongation;                  // genes x probes: sqrt(w_p) delta_p
  };

  // Per gene e: S_e sum_p sqrt(w_p) delta_pe g_e^T z_p.
  Vector ColumnProducts(const Part& part, const Matrix& z) const;
  // B <- C B on the part's support, in chunks between stop checks.
  void SolveColumns(const SupportSystem& system, Matrix& b) const;
  // f(part i) for every part, in parallel on the pool.
  void Run(const std::function<void(std::size_t)>& f) const;
  // The sum over the parts of a per-gene vector each computes, in support order.
  Vector Sum(const std::function<Vector(const Part&)>& f) const;

  const ProbeObjective* objective_;
  const GeneSprings* springs_;
  Interruption* interruption_;
  WorkerPool* pool_;
  std::vector<Part> parts_;
};

}  // namespace springfit::response
