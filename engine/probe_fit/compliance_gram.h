// The probe fit's normal equations: a sum of compliance-weighted force residuals, quadratic in
// the springs' stiffness k (docs/ARCHITECTURE.md, "The probe fit"; proto/RUN.md, the dense fit).
//
// A spring e over nodes (i, j) with unit rest direction n_e has the force column
// g_e = (-n_e on i, +n_e on j); at a displacement u its elongation is delta_e = g_e^T u, and the
// rest stiffness of a model is K(k) = sum_e k_e g_e g_e^T, so K(k) u = A(u) k with
// A(u) = [g_e delta_e]. For probes p on supports s (free degrees of freedom only), with a dense
// symmetric C_s and targets t_p,
//   f(k) = sum_p w_p |C_s A(u_p) k - t_p|^2 = k^T H k - 2 c^T k + constant,
//   H_ee' = sum_s (g_e^T C_s^2 g_e') (sum_{p on s} w_p delta_pe delta_pe'),
//   c_e   = sum_p w_p delta_pe (g_e^T C_s t_p),   constant = sum_p w_p |t_p|^2.
// Two fits use it:
// - the first-order (convex) fit: C_s = K_ref^-1 on s, u_p the reference's displacement and
//   t_p = C_s f_p. Then C_s (A k - f) = C_s (K(k) - K_ref) u_p is the model's displacement error
//   to first order in K(k) - K_ref: compliance-weighted stiffness matching;
// - a Gauss-Newton step of the exact fit: C_s = K(k0)^-1, u_p the model's displacement and
//   t_p = u_p - u_ref,p + C_s f_p: the linearisation of u(k) - u_ref about k0.
// H costs m^2 (2d + probes) per support and m^2 doubles of memory (m the genes).
#pragma once

#include <vector>

#include "engine/probe_fit/support_system.h"
#include "engine/problem/problem.h"
#include "engine/runtime/worker_pool.h"

namespace springfit::response {

// Per gene, its spring's nodes and unit rest direction.
struct GeneSprings {
  int dimension = 2;
  std::vector<NodePair> pairs;
  Matrix directions;  // d x genes
  int size() const { return static_cast<int>(pairs.size()); }
};
GeneSprings GeneSpringsOf(const Problem& problem);

// The springs of some genes, in the order given.
GeneSprings Subset(const GeneSprings& springs, const std::vector<int>& genes);

// g_e's entries on a support's free degrees of freedom: up to 2d (index, value) pairs.
struct SpringColumn {
  int count = 0;
  int index[6];
  double value[6];
  // g_e^T z for z on the support's free degrees of freedom.
  double Dot(const double* z) const {
    double v = 0.0;
    for (int a = 0; a < count; ++a) v += value[a] * z[index[a]];
    return v;
  }
  // y += s g_e.
  void AddTo(double s, double* y) const {
    for (int a = 0; a < count; ++a) y[index[a]] += s * value[a];
  }
};
std::vector<SpringColumn> FreeColumns(const GeneSprings& springs, const SupportSystem& support);

// delta_e = g_e^T u for every gene (u flat d*n).
Vector Elongations(const GeneSprings& springs, const Vector& u);

struct GramTerm {
  int support = 0;
  double weight = 0.0;
  Vector elongation;  // delta_p, per gene
  Vector target;      // t_p, on the support's free degrees of freedom
};

struct Gram {
  Matrix H;
  Vector c;
  double constant = 0.0;
  // f(k) for per-gene weights k.
  double Value(const Vector& k) const { return k.dot(H * k) - 2.0 * c.dot(k) + constant; }
};

// `compliance[s]` is C_s (dense, the support's free degrees of freedom). Supports without a
// term are skipped (their compliance may be empty). With a pool the supports' parts are
// computed in parallel (each support's part holds m^2 doubles until they are summed).
Gram BuildGram(const GeneSprings& springs, const std::vector<SupportSystem>& supports,
               const std::vector<Matrix>& compliance, const std::vector<GramTerm>& terms,
               WorkerPool* pool = nullptr);

}  // namespace springfit::response
