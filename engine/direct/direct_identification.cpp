#include "engine/direct/direct_identification.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "engine/direct/weight_uncertainty.h"

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
  const std::vector<bool> usable = SeenGenes(fb, options.unseen_strain);
  for (int g = 0; g < genes; ++g) {
    if (!usable[g]) r.unseen.push_back(g);
  }
  r.assemble_seconds = SecondsSince(start);

  start = std::chrono::steady_clock::now();
  r.nnls = SolveNnls(fb.a, fb.b, usable, options.nnls);
  r.weights.assign(r.nnls.x.data(), r.nnls.x.data() + r.nnls.x.size());
  // The residual variance over the degrees of freedom left by the positive weights.
  int positive = 0;
  for (int g = 0; g < genes; ++g) positive += r.weights[g] > 0.0;
  const double dof = std::max<double>(static_cast<double>(fb.a.rows()) - positive, 1.0);
  const double variance = (fb.a * r.nnls.x - fb.b).squaredNorm() / dof;
  // Exact data (an MSS reference: the force balance holds to round-off) needs no standard
  // errors: its absent springs sit at round-off, below the relative floor. They would cost
  // one solve per gene, several times the identification itself.
  const double b_norm = std::max(fb.b.norm(), 1e-300);
  const bool exact_data = (fb.a * r.nnls.x - fb.b).norm() <= options.exact_data_residual * b_norm;
  std::optional<Vector> sigma;
  if (!exact_data && options.refine) {
    const RefinementResult refinement = RefineWeights(problem, r.weights, usable, options.refinement);
    if (refinement.refined) {
      r.refined = true;
      r.refinement_iterations = refinement.iterations;
      r.weights = refinement.weights;
      if (!refinement.sigma.empty()) sigma = Eigen::Map<const Vector>(refinement.sigma.data(), genes);
    }
  }
  // Noisy data never go without standard errors when they can be had: the relative floor
  // alone lets every spurious weight in.
  if (!exact_data && !sigma) sigma = WeightStandardErrors(fb.a, usable, variance, options.uncertainty_max_genes);
  const double largest = genes > 0 ? *std::max_element(r.weights.begin(), r.weights.end()) : 0.0;
  const double floor = options.relative_threshold * largest;
  if (sigma) {
    r.sigma.assign(sigma->data(), sigma->data() + sigma->size());
    r.confidence.assign(genes, std::numeric_limits<double>::quiet_NaN());
  }
  r.genome.assign(genes, 0);
  Vector kept = Vector::Zero(genes);
  for (int g = 0; g < genes; ++g) {
    if (!usable[g]) continue;
    double threshold = floor;
    if (sigma) {
      const double s = (*sigma)[g];
      threshold = std::max(floor, options.significance * s);
      r.confidence[g] = s > 0.0 ? (r.weights[g] - threshold) / s : (r.weights[g] > threshold ? HUGE_VAL : -HUGE_VAL);
    }
    if (largest > 0.0 && r.weights[g] > threshold) {
      r.genome[g] = 1;
      kept[g] = r.weights[g];
      r.springs.index.push_back(problem.gene_candidates()[g]);
      r.springs.stiffness.push_back(r.weights[g]);
    }
  }
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
