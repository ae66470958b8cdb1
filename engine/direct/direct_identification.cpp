#include "engine/direct/direct_identification.h"

#include <algorithm>
#include <chrono>

namespace springfit {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

DirectResult IdentifyDirect(const Problem& problem, const DirectOptions& options) {
  DirectResult r;
  auto start = std::chrono::steady_clock::now();
  const ForceBalance fb = AssembleForceBalance(problem);
  const int genes = problem.gene_count();
  std::vector<bool> usable(genes, true);
  for (int g = 0; g < genes; ++g) {
    if (fb.strain[g] < options.unseen_strain) {
      usable[g] = false;
      r.unseen.push_back(g);
    }
  }
  r.assemble_seconds = SecondsSince(start);

  start = std::chrono::steady_clock::now();
  r.nnls = SolveNnls(fb.a, fb.b, usable, options.nnls);
  r.weights.assign(r.nnls.x.data(), r.nnls.x.data() + r.nnls.x.size());
  const double largest = r.nnls.x.size() > 0 ? r.nnls.x.maxCoeff() : 0.0;
  r.genome.assign(genes, 0);
  Vector kept = Vector::Zero(genes);
  for (int g = 0; g < genes; ++g) {
    if (largest > 0.0 && r.weights[g] > options.relative_threshold * largest) {
      r.genome[g] = 1;
      kept[g] = r.weights[g];
      r.springs.index.push_back(problem.gene_candidates()[g]);
      r.springs.stiffness.push_back(r.weights[g]);
    }
  }
  const double b_norm = std::max(fb.b.norm(), 1e-300);
  r.force_residual = (fb.a * kept - fb.b).norm() / b_norm;
  r.nnls_residual = (fb.a * r.nnls.x - fb.b).norm() / b_norm;
  r.solve_seconds = SecondsSince(start);

  start = std::chrono::steady_clock::now();
  CostFunction cost(problem);
  r.evaluation = cost.Evaluate(r.springs);
  r.evaluate_seconds = SecondsSince(start);
  return r;
}

}  // namespace springfit
