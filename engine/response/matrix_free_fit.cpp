#include "engine/response/matrix_free_fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>

#include "engine/fit/stiffness_fit.h"
#include "engine/response/compliance_gram.h"
#include "engine/response/probe_objective.h"
#include "engine/search/random_stream.h"

namespace springfit::response {
namespace {

constexpr double kNoModel = std::numeric_limits<double>::infinity();
// Right-hand sides solved in one call between stop checks.
constexpr Eigen::Index kSolveChunk = 16;

// The model linearised at one point: per fitted support its factorisation, and per fitted probe
// on it the weighted residual and elongations.
class Linearization {
 public:
  Linearization(const ProbeObjective& objective, const GeneSprings& springs,
                Interruption* interruption, WorkerPool* pool)
      : objective_(&objective), springs_(&springs), interruption_(interruption), pool_(pool) {}

  // False when some fitted support does not hold the model (a mechanism).
  bool At(const std::vector<double>& weights) {
    const Problem& problem = objective_->problem();
    const ProbeBank& bank = objective_->bank();
    const SparseMatrix k = SpringRestStiffness(problem, weights);
    const std::vector<std::size_t>& used = objective_->fitted_supports();
    parts_.clear();
    for (std::size_t s : used) {
      Part part{s, SupportSystem(problem.dimension(), bank.supports[s].constrained), {}, {}, {},
                {}};
      for (std::size_t p = 0; p < bank.probes.size(); ++p)
        if (objective_->weight()[p] > 0.0 && bank.probes[p].support == static_cast<int>(s))
          part.probes.push_back(static_cast<int>(p));
      parts_.push_back(std::move(part));
    }
    std::vector<char> held(parts_.size(), 0);
    Run([&](std::size_t i) {
      Part& part = parts_[i];
      if (!(held[i] = part.system.Factorize(k))) return;
      part.columns = FreeColumns(*springs_, part.system);
      const auto count = static_cast<Eigen::Index>(part.probes.size());
      const int n = part.system.free_dofs();
      Matrix u(n, count);
      std::vector<Vector> prescribed(part.probes.size());
      for (Eigen::Index j = 0; j < count; ++j) {
        const Probe& probe = bank.probes[static_cast<std::size_t>(part.probes[j])];
        u.col(j) = part.system.RightHandSide(probe.force, probe.prescribed);
      }
      SolveColumns(part.system, u);
      part.residual.resize(n, count);
      part.elongation.resize(springs_->size(), count);
      for (Eigen::Index j = 0; j < count; ++j) {
        const std::size_t p = static_cast<std::size_t>(part.probes[j]);
        const Probe& probe = bank.probes[p];
        const double root = std::sqrt(objective_->weight()[p]);
        Vector constrained_part = probe.prescribed;
        for (int dof : part.system.free_dof_list()) constrained_part[dof] = 0.0;
        const Vector full = part.system.Scatter(u.col(j), constrained_part);
        part.residual.col(j) = root * (u.col(j) - part.system.Gather(probe.reference));
        part.elongation.col(j) = root * Elongations(*springs_, full);
      }
    });
    return std::find(held.begin(), held.end(), 0) == held.end();
  }

  // sum_p w_p |u_p - u_ref,p|^2.
  double ResidualNorm2() const {
    double sum = 0.0;
    for (const Part& part : parts_) sum += part.residual.squaredNorm();
    return sum;
  }

  // J^T r in the scaled variables.
  Vector Gradient() const {
    return Sum([&](const Part& part) {
      Matrix z = part.residual;
      SolveColumns(part.system, z);
      return Vector(-ColumnProducts(part, z));  // (evaluated before the temporary goes)
    });
  }

  // J^T J v in the scaled variables.
  Vector NormalProduct(const Vector& v) const {
    const Vector sv = v.cwiseProduct(objective_->scale());
    return Sum([&](const Part& part) {
      const auto count = static_cast<Eigen::Index>(part.probes.size());
      Matrix y = Matrix::Zero(part.system.free_dofs(), count);
      for (Eigen::Index j = 0; j < count; ++j) {
        double* column = y.col(j).data();
        for (int e = 0; e < springs_->size(); ++e) {
          const double a = part.elongation(e, j) * sv[e];
          if (a != 0.0) part.columns[static_cast<std::size_t>(e)].AddTo(a, column);
        }
      }
      SolveColumns(part.system, y);
      SolveColumns(part.system, y);
      return ColumnProducts(part, y);
    });
  }

  // J^T J's diagonal: S_e^2 sum_p w_p delta_pe^2 |C g_e|^2, with |C g_e|^2 estimated from
  // `samples` random sign vectors z (E[(g_e^T C z)^2] = |C g_e|^2), seeded per support.
  Vector NormalDiagonal(int samples, std::uint64_t seed) const {
    const Vector scale2 = objective_->scale().cwiseAbs2();
    return Sum([&](const Part& part) {
      const int n = part.system.free_dofs();
      RandomStream random(seed * 1000003u + part.support);
      Matrix z(n, samples);
      for (int c = 0; c < samples; ++c)
        for (int i = 0; i < n; ++i) z(i, c) = random.Uniform() < 0.5 ? -1.0 : 1.0;
      SolveColumns(part.system, z);
      Vector diagonal(springs_->size());
      for (int e = 0; e < springs_->size(); ++e) {
        double compliance2 = 0.0;
        for (int c = 0; c < samples; ++c) {
          const double t = part.columns[static_cast<std::size_t>(e)].Dot(z.col(c).data());
          compliance2 += t * t;
        }
        diagonal[e] = scale2[e] * part.elongation.row(e).squaredNorm() * compliance2 / samples;
      }
      return diagonal;
    });
  }

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
  Vector ColumnProducts(const Part& part, const Matrix& z) const {
    Vector out = Vector::Zero(springs_->size());
    for (Eigen::Index j = 0; j < z.cols(); ++j) {
      const double* column = z.col(j).data();
      for (int e = 0; e < springs_->size(); ++e) {
        const double a = part.elongation(e, j);
        if (a != 0.0) out[e] += a * part.columns[static_cast<std::size_t>(e)].Dot(column);
      }
    }
    return out.cwiseProduct(objective_->scale());
  }

  void SolveColumns(const SupportSystem& system, Matrix& b) const {
    for (Eigen::Index first = 0; first < b.cols(); first += kSolveChunk) {
      ThrowIfInterrupted(interruption_);
      const Eigen::Index count = std::min(kSolveChunk, b.cols() - first);
      Matrix chunk = b.middleCols(first, count);
      system.SolveColumns(chunk);
      b.middleCols(first, count) = chunk;
    }
  }

  // f(part i) for every part, in parallel on the pool.
  void Run(const std::function<void(std::size_t)>& f) const {
    RunSlots(
        pool_, static_cast<int>(parts_.size()),
        [&](int slot) { f(static_cast<std::size_t>(slot)); },
        [this] {
          if (interruption_) interruption_->Check();
        });
    ThrowIfInterrupted(interruption_);
  }

  // The sum over the parts of a per-gene vector each computes, in support order.
  Vector Sum(const std::function<Vector(const Part&)>& f) const {
    std::vector<Vector> each(parts_.size());
    Run([&](std::size_t i) { each[i] = f(parts_[i]); });
    Vector total = Vector::Zero(springs_->size());
    for (const Vector& v : each) total += v;
    return total;
  }

  const ProbeObjective* objective_;
  const GeneSprings* springs_;
  Interruption* interruption_;
  WorkerPool* pool_;
  std::vector<Part> parts_;
};

// Jacobi-preconditioned conjugate gradients for A d = b on the entries where `free` holds (d is
// 0 elsewhere); at most `iterations`, or until the residual falls below `tolerance` |b|.
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
  const ProbeObjective objective(problem, bank, reference_stiffness, prior, options);
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

  // Gauss-Newton steps at one strength from `weights` (springs with `removed` set stay out);
  // returns the steps accepted, each judged.
  int step_count = 0;
  const auto descend = [&](std::vector<double>& weights, Linearization& at, double regularization,
                           int steps, const std::vector<bool>& removed) {
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
        Linearization next(objective, springs, interruption, pool);
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
  Linearization at(objective, springs, interruption, pool);
  const std::vector<bool> none(prior.size(), false);
  judge(weights, options.regularizations.front(), 0);
  if (at.At(weights)) {
    std::vector<double> strengths = options.regularizations;
    std::sort(strengths.begin(), strengths.end(), std::greater<>());
    for (double strength : strengths) {
      const std::size_t before = iterates.size();
      descend(weights, at, strength, options.steps_per_strength, none);
      r.regularizations.push_back(strength);
      const Iterate& last = iterates.back();
      r.regularization_select_errors.push_back(iterates.size() > before ? last.select_error
                                                                        : kNoModel);
      r.regularization_lambda_min.push_back(iterates.size() > before ? last.lambda_min : 0.0);
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
    Linearization budget(objective, springs, interruption, pool);
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
