#include "engine/response/matrix_free_fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>

#include "engine/fit/stiffness_fit.h"
#include "engine/response/linearized_response.h"
#include "engine/response/probe_objective.h"

namespace springfit::response {
namespace {

// Jacobi-preconditioned conjugate gradients for A d = b on the entries where `free` holds (d is
// 0 elsewhere); at most `iterations`, or until the residual falls below `tolerance` |b|.
// (Eigen's ConjugateGradient takes a matrix-free operator only as a sparse-matrix-like
// expression type; a closure over the masked products is the shorter and clearer form here.)
Vector ConjugateGradients(const std::function<Vector(const Vector&)>& multiply, const Vector& b,
                          const Vector& diagonal, const std::vector<bool>& free, int iterations,
                          double tolerance) {
  const Eigen::Index m = b.size();
  Vector mask(m);
  for (Eigen::Index e = 0; e < m; ++e) mask[e] = free[static_cast<std::size_t>(e)] ? 1.0 : 0.0;
  Vector d = Vector::Zero(m);
  Vector r = b.cwiseProduct(mask);
  const double target = tolerance * r.norm();
  Vector z = r.cwiseQuotient(diagonal);
  Vector p = z;
  double rz = r.dot(z);
  for (int it = 0; it < iterations && r.norm() > target; ++it) {
    const Vector ap = multiply(p).cwiseProduct(mask);
    const double curvature = p.dot(ap);
    if (!(curvature > 0.0)) break;
    const double alpha = rz / curvature;
    d += alpha * p;
    r -= alpha * ap;
    z = r.cwiseQuotient(diagonal);
    const double rz_next = r.dot(z);
    p = z + (rz_next / rz) * p;
    rz = rz_next;
  }
  return d;
}

}  // namespace

ResponseFitResult FitResponseMatrixFree(const Problem& problem, const ProbeBank& bank,
                                        const SparseMatrix& reference_stiffness,
                                        const std::vector<double>& prior,
                                        const ResponseFitOptions& options,
                                        Interruption* interruption,
                                        const ResponseProgress& progress, WorkerPool* pool) {
  const auto started = std::chrono::steady_clock::now();
  const auto seconds = [&started] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  };
  const ProbeObjective objective(problem, bank, reference_stiffness, prior, options, interruption);
  const GeneSprings springs = GeneSpringsOf(problem);
  const double genes = static_cast<double>(problem.gene_count());
  ResponseFitResult r;
  r.method = "matrix-free";

  // Every accepted iterate with its strength, choosing error and smallest eigenvalue.
  struct Iterate {
    std::vector<double> weights;
    double regularization = 0.0;
    double select_error = kNoModel;
    double lambda_min = 0.0;
    int step = 0;
  };
  std::vector<Iterate> iterates;
  const auto judge = [&](const std::vector<double>& weights, double regularization, int step) {
    Iterate it{weights, regularization, objective.SelectError(weights),
               objective.LambdaMin(weights), step};
    iterates.push_back(std::move(it));
    double best = kNoModel;
    for (const Iterate& i : iterates) best = std::min(best, i.select_error);
    if (progress) progress("probe_fit", best);
  };

  // Gauss-Newton steps at one strength from `weights`, `at` its linearisation (springs with
  // `removed` set stay out); each accepted step is judged, and `weights` and `at` follow it.
  int step_count = 0;
  const auto descend = [&](std::vector<double>& weights, LinearizedResponse& at,
                           double regularization, int steps, const std::vector<bool>& removed) {
    const double rho = regularization / genes;
    Vector x = objective.Scaled(weights);
    double phi = at.ResidualNorm2() + objective.Regularization(weights, regularization);
    for (int step = 0; step < steps; ++step) {
      const Vector gradient = at.Gradient() + rho * (x - objective.prior_scaled());
      std::vector<bool> free(static_cast<std::size_t>(x.size()));
      for (Eigen::Index e = 0; e < x.size(); ++e)
        free[static_cast<std::size_t>(e)] =
            !removed[static_cast<std::size_t>(e)] && !(x[e] <= 0.0 && gradient[e] > 0.0);
      Vector diagonal = at.NormalDiagonal(options.diagonal_samples, options.probes.seed);
      diagonal.array() += rho;
      const Vector d = ConjugateGradients(
          [&](const Vector& v) { return Vector(at.NormalProduct(v) + rho * v); }, -gradient,
          diagonal, free, options.cg_iterations, options.cg_tolerance);
      bool accepted = false;
      for (int halving = 0; halving < 4 && !accepted; ++halving) {
        const double t = std::ldexp(1.0, -halving);
        const Vector trial_x = (x + t * d).cwiseMax(0.0);
        const std::vector<double> trial = objective.Weights(trial_x);
        if (PresentSprings(trial) == 0) continue;
        LinearizedResponse next(objective, springs, interruption, pool);
        if (!next.At(trial)) continue;
        const double value = next.ResidualNorm2() + objective.Regularization(trial, regularization);
        if (!(value < phi)) continue;
        weights = trial;
        x = objective.Scaled(trial);
        phi = value;
        at = std::move(next);
        accepted = true;
      }
      if (!accepted) break;
      judge(weights, regularization, ++step_count);
    }
  };

  std::vector<double> weights = objective.Weights(objective.prior_scaled());
  LinearizedResponse at(objective, springs, interruption, pool);
  const std::vector<bool> none(prior.size(), false);
  judge(weights, options.regularizations.front(), 0);
  if (at.At(weights)) {
    std::vector<double> strengths = options.regularizations;
    std::sort(strengths.begin(), strengths.end(), std::greater<>());
    for (double strength : strengths) {
      descend(weights, at, strength, options.steps_per_strength, none);
      // The model at this strength: its last accepted step's, or the one it started from when
      // none was accepted.
      r.regularizations.push_back(strength);
      r.regularization_select_errors.push_back(iterates.back().select_error);
      r.regularization_lambda_min.push_back(iterates.back().lambda_min);
    }
  }
  r.seconds_first_order = seconds();

  // The best iterate on the choosing probes, preferring one that holds every mode.
  const auto best_of = [&](std::size_t from) {
    std::vector<double> errors, lambdas;
    for (std::size_t i = from; i < iterates.size(); ++i) {
      errors.push_back(iterates[i].select_error);
      lambdas.push_back(iterates[i].lambda_min);
    }
    const std::vector<double> score = PreferSupported(errors, lambdas, options);
    return from +
           static_cast<std::size_t>(std::min_element(score.begin(), score.end()) - score.begin());
  };
  std::size_t chosen = best_of(0);
  r.path.push_back({PresentSprings(iterates[chosen].weights), iterates[chosen].select_error,
                    iterates[chosen].lambda_min});

  // A spring budget: the least salient springs of the chosen model out, the rest refitted.
  if (options.max_springs > 0 && r.path.back().springs > options.max_springs) {
    weights = iterates[chosen].weights;
    const double regularization = iterates[chosen].regularization;
    LinearizedResponse budget(objective, springs, interruption, pool);
    if (budget.At(weights)) {
      const Vector x = objective.Scaled(weights);
      const Vector diagonal = budget.NormalDiagonal(options.diagonal_samples, options.probes.seed);
      std::vector<std::pair<double, int>> saliency;
      for (int e = 0; e < x.size(); ++e)
        if (x[e] > 0.0) saliency.emplace_back(0.5 * x[e] * x[e] * diagonal[e], e);
      std::sort(saliency.begin(), saliency.end());
      std::vector<bool> removed(prior.size(), false);
      const std::size_t cut = saliency.size() - static_cast<std::size_t>(options.max_springs);
      for (std::size_t i = 0; i < cut; ++i) {
        removed[static_cast<std::size_t>(saliency[i].second)] = true;
        weights[static_cast<std::size_t>(saliency[i].second)] = 0.0;
      }
      const std::size_t first = iterates.size();
      judge(weights, regularization, step_count);
      if (budget.At(weights)) {
        if (progress) progress("probe_path", iterates.back().select_error);
        descend(weights, budget, regularization, options.steps_per_strength, removed);
      }
      const std::size_t within = best_of(first);
      r.path.push_back({PresentSprings(iterates[within].weights), iterates[within].select_error,
                        iterates[within].lambda_min});
      if (iterates[within].select_error < kNoModel && iterates[within].lambda_min > 0.0) {
        chosen = within;
        r.chosen = 1;
      }
    }
  }
  const Iterate& returned = iterates[chosen];
  r.weights = returned.weights;
  r.regularization = returned.regularization;
  r.select_error = returned.select_error;
  r.lambda_min = returned.lambda_min;
  r.gauss_newton_accepted = returned.step;
  r.seconds_path = seconds() - r.seconds_first_order;
  return r;
}

}  // namespace springfit::response
