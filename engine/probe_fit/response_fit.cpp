#include "engine/probe_fit/response_fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <optional>

#include "engine/fit/stiffness_fit.h"
#include "engine/probe_fit/compliance_gram.h"
#include "engine/probe_fit/matrix_free_fit.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/probe_fit/probe_objective.h"
#include "engine/runtime/options_check.h"
#include "engine/runtime/wall_clock.h"

namespace springfit::response {
namespace {

// The fit in scaled variables x = k / scale: q(x) = 1/2 x^T A x - b^T x.
struct ScaledQuadratic {
  Matrix A;
  Vector b;
};

// The regularisation is a mean over `genes` (every gene, also where the quadratic covers only
// some of them).
ScaledQuadratic Scaled(const Gram& gram, const Vector& scale, double regularization,
                       const Vector& prior_scaled, Eigen::Index genes) {
  const double m = static_cast<double>(genes);
  ScaledQuadratic q;
  q.A = 2.0 * scale.asDiagonal() * gram.H * scale.asDiagonal();
  q.b = 2.0 * scale.cwiseProduct(gram.c);
  q.A.diagonal().array() += 2.0 * regularization / m;
  q.b += (2.0 * regularization / m) * prior_scaled;
  return q;
}

// The dense fit's Gram matrices (compliance_gram.h) over the objective's probes.
class Fit : public ProbeObjective {
 public:
  Fit(const Problem& problem, const ProbeBank& bank, const SparseMatrix& reference_stiffness,
      const std::vector<double>& prior, const ResponseFitOptions& options,
      Interruption* interruption, WorkerPool* pool)
      : ProbeObjective(problem, bank, reference_stiffness, prior, options, interruption),
        pool_(pool),
        interruption_(interruption),
        springs_(GeneSpringsOf(problem)) {}

  // The first-order Gram matrix over the fitted probes, normalised so that its value is the
  // weighted mean squared relative error.
  Gram FirstOrderGram() {
    if (interruption_ && interruption_->Check()) throw Interrupted();
    std::vector<Matrix> compliance(bank().supports.size());
    ForFittedSupports([&](std::size_t s) { compliance[s] = reference()[s].Compliance(); });
    if (interruption_ && interruption_->Check()) throw Interrupted();
    std::vector<GramTerm> terms;
    for (std::size_t p = 0; p < bank().probes.size(); ++p) {
      if (!(weight()[p] > 0.0)) continue;
      const Probe& probe = bank().probes[p];
      const SupportSystem& system = reference()[static_cast<std::size_t>(probe.support)];
      const Matrix& c = compliance[static_cast<std::size_t>(probe.support)];
      GramTerm term;
      term.support = probe.support;
      term.weight = weight()[p];
      term.elongation = Elongations(springs_, probe.reference);
      term.target = c * system.Gather(probe.force);
      terms.push_back(std::move(term));
    }
    return BuildGram(springs_, reference(), compliance, terms, pool_);
  }

  // f(s) for every support with a fitted probe, in parallel on the pool (each its own s).
  void ForFittedSupports(const std::function<void(std::size_t)>& f) {
    const std::vector<std::size_t>& used = fitted_supports();
    // (While the pool works, the owner keeps polling: progress beats and stop requests go on.)
    RunSlots(
        pool_, static_cast<int>(used.size()),
        [&](int slot) { f(used[static_cast<std::size_t>(slot)]); },
        [this] {
          if (interruption_) interruption_->Check();
        });
  }

  // The Gauss-Newton Gram of the exact error about `weights`; false when the model is not held
  // by some fitted support.
  bool GaussNewtonGram(const std::vector<double>& weights, const GeneSprings& springs, Gram& gram) {
    if (interruption_ && interruption_->Check()) throw Interrupted();
    const SparseMatrix k = SpringRestStiffness(problem(), weights);
    std::vector<SupportSystem> model;
    std::vector<Matrix> compliance(bank().supports.size());
    for (const Support& support : bank().supports)
      model.emplace_back(problem().dimension(), support.constrained);
    std::vector<char> held(bank().supports.size(), 1);
    ForFittedSupports([&](std::size_t s) {
      held[s] = model[s].Factorize(k);
      if (held[s]) compliance[s] = model[s].Compliance();
    });
    if (std::find(held.begin(), held.end(), 0) != held.end()) return false;
    if (interruption_ && interruption_->Check()) throw Interrupted();
    std::vector<GramTerm> terms;
    for (std::size_t p = 0; p < bank().probes.size(); ++p) {
      if (!(weight()[p] > 0.0)) continue;
      const Probe& probe = bank().probes[p];
      const SupportSystem& system = model[static_cast<std::size_t>(probe.support)];
      const Matrix& c = compliance[static_cast<std::size_t>(probe.support)];
      const Vector u = system.Displacement(probe.force, probe.prescribed);
      GramTerm term;
      term.support = probe.support;
      term.weight = weight()[p];
      term.elongation = Elongations(springs, u);
      term.target = system.Gather(u - probe.reference) + c * system.Gather(probe.force);
      terms.push_back(std::move(term));
    }
    gram = BuildGram(springs, model, compliance, terms, pool_);
    return true;
  }

  const GeneSprings& springs() const { return springs_; }

 private:
  WorkerPool* pool_;
  Interruption* interruption_;
  GeneSprings springs_;
};

}  // namespace

void ResponseFitOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  probes.Validate(check.Nested("probes"));
  nnls.Validate(check.Nested("nnls"));
  check.Require(!regularizations.empty(), "regularizations", 0.0, "at least one strength");
  for (double r : regularizations)
    check.Require(r >= 0.0 && std::isfinite(r), "regularizations", r, "every value >= 0");
  check.Require(InOpenUnit(prune_fraction), "prune_fraction", prune_fraction, "0 < value < 1");
  check.Require(max_error_growth > 1.0, "max_error_growth", max_error_growth, "value > 1");
  check.Require(max_retries >= 0, "max_retries", max_retries, "value >= 0");
  check.Require(max_path_points >= 1, "max_path_points", max_path_points, "value >= 1");
  check.Require(stop_error_factor > 1.0, "stop_error_factor", stop_error_factor, "value > 1");
  check.Require(tolerance >= 0.0, "tolerance", tolerance, "value >= 0");
  check.Require(dust >= 0.0 && dust < 1.0, "dust", dust, "0 <= value < 1");
  check.Require(max_spread == 0.0 || (max_spread > 1.0 && std::isfinite(max_spread)), "max_spread",
                max_spread, "value > 1 (0: none)");
  check.Require(max_springs >= 0, "max_springs", max_springs, "value >= 0 (0: none)");
  check.Require(min_lambda >= 0.0 && min_lambda < 1.0, "min_lambda", min_lambda, "0 <= value < 1");
  check.Require(lambda_slack >= 0.0, "lambda_slack", lambda_slack, "value >= 0");
  check.Require(gauss_newton_steps >= 0, "gauss_newton_steps", gauss_newton_steps, "value >= 0");
  check.Require(dense_max_genes >= 0, "dense_max_genes", dense_max_genes,
                "value >= 0 (0: never dense)");
  check.Require(steps_per_strength >= 1, "steps_per_strength", steps_per_strength, "value >= 1");
  check.Require(cg_iterations >= 1, "cg_iterations", cg_iterations, "value >= 1");
  check.Require(InOpenUnit(cg_tolerance), "cg_tolerance", cg_tolerance, "0 < value < 1");
  check.Require(diagonal_samples >= 1, "diagonal_samples", diagonal_samples, "value >= 1");
  lift.Validate(check.Nested("lift"));
  hold.Validate(check.Nested("hold"));
  check.Require(hold.weight == 0.0 || hold.target >= min_lambda, "hold.target", hold.target,
                "value >= min_lambda (the cuts hold the modes a little above it)");
  check.Require(continuation_patience >= 0, "continuation_patience", continuation_patience,
                "value >= 0 (0: every strength)");
  check.Require(soft_mode_rounds >= 0, "soft_mode_rounds", soft_mode_rounds, "value >= 0");
  check.Require(soft_modes_per_round >= 1, "soft_modes_per_round", soft_modes_per_round,
                "value >= 1");
}

namespace {

using Tell = std::function<void(const char* phase, double error)>;

// Among models (finite error, every support holding them) within the spring budget, the best,
// preferring one that holds every mode when nearly as good; nothing without a budget or when
// no model is within it.
std::optional<std::size_t> BestWithinBudget(const std::vector<int>& springs,
                                            const std::vector<double>& errors,
                                            const std::vector<double>& lambdas,
                                            const ResponseFitOptions& options) {
  if (options.max_springs == 0) return std::nullopt;
  std::vector<std::size_t> models;
  std::vector<double> model_errors, model_lambdas;
  for (std::size_t i = 0; i < springs.size(); ++i) {
    if (springs[i] <= options.max_springs && lambdas[i] > 0.0 && errors[i] < kNoModel) {
      models.push_back(i);
      model_errors.push_back(errors[i]);
      model_lambdas.push_back(lambdas[i]);
    }
  }
  if (models.empty()) return std::nullopt;
  const std::vector<double> score = PreferSupported(model_errors, model_lambdas, options);
  return models[static_cast<std::size_t>(std::min_element(score.begin(), score.end()) -
                                         score.begin())];
}

// The dense fit's first-order fit at every strength, strongest first, each solve started from the
// previous one's solution (continuation: the strongly regularised problem is well conditioned,
// and each weaker one starts near its answer). Records each strength's model in `r` and sets
// r.regularization to the chosen one; returns its solution (scaled variables) and choosing
// error.
struct PathStart {
  Vector x;
  double error = kNoModel;
};
PathStart FirstOrderFits(const Fit& fit, const Gram& gram, const ResponseFitOptions& options,
                         Interruption* interruption, const Tell& tell, ResponseFitResult& r) {
  std::vector<std::size_t> order(options.regularizations.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return options.regularizations[a] > options.regularizations[b];
  });
  r.regularizations = options.regularizations;
  r.regularization_select_errors.assign(r.regularizations.size(), kNoModel);
  r.regularization_lambda_min.assign(r.regularizations.size(), 0.0);
  Vector previous = fit.prior_scaled();
  std::vector<Vector> solutions(r.regularizations.size());
  for (std::size_t i : order) {
    const ScaledQuadratic q =
        Scaled(gram, fit.scale(), r.regularizations[i], fit.prior_scaled(), fit.scale().size());
    const QuadraticNnlsResult solved =
        SolveQuadraticNnls(q.A, q.b, previous, {}, options.nnls, interruption);
    previous = solutions[i] = solved.x;
    const std::vector<double> weights = fit.Weights(solved.x);
    r.regularization_select_errors[i] = fit.SelectError(weights);
    r.regularization_lambda_min[i] = fit.LambdaMin(weights);
    tell("probe_fit", *std::min_element(r.regularization_select_errors.begin(),
                                        r.regularization_select_errors.end()));
  }
  // The lowest choosing error, preferring models that support every mode (the weaker strength
  // on a tie within 0.1%).
  const std::vector<double> score =
      PreferSupported(r.regularization_select_errors, r.regularization_lambda_min, options);
  double best = kNoModel;
  Vector best_x;
  for (std::size_t i : order) {
    if (score[i] <= best * (1.0 + 1e-3)) {
      best = std::min(best, score[i]);
      r.regularization = r.regularizations[i];
      best_x = solutions[i];
    }
  }
  if (best_x.size() == 0) best_x = fit.prior_scaled();  // (every model a mechanism)
  return {best_x, best};
}

// One point of the sparsity path removed: the least salient springs of `x` out (saliency
// 1/2 x_e^2 A_ee), the rest refitted; a removal that raises the choosing error by more than
// max_error_growth is retried with half as many springs (the saliencies ignore how springs
// stand in for each other). Returns the next point's weights and sets `error` to its choosing
// error; nothing when no spring is left to remove.
std::optional<std::vector<double>> PrunePoint(const Fit& fit, const ScaledQuadratic& q,
                                              const Vector& x, const ResponseFitOptions& options,
                                              Interruption* interruption, double& error) {
  std::vector<std::pair<double, int>> saliency;
  for (int e = 0; e < x.size(); ++e)
    if (x[e] > 0.0) saliency.emplace_back(0.5 * x[e] * x[e] * q.A(e, e), e);
  const auto remove = static_cast<std::size_t>(
      std::ceil(options.prune_fraction * static_cast<double>(saliency.size())));
  if (saliency.size() <= 1 || remove == 0) return std::nullopt;
  std::sort(saliency.begin(), saliency.end());
  const double before = error;
  std::size_t count = remove;
  for (int attempt = 0;; ++attempt) {
    std::vector<bool> fixed(static_cast<std::size_t>(x.size()));
    for (int e = 0; e < x.size(); ++e) fixed[static_cast<std::size_t>(e)] = !(x[e] > 0.0);
    for (std::size_t i = 0; i < count; ++i)
      fixed[static_cast<std::size_t>(saliency[i].second)] = true;
    const QuadraticNnlsResult solved =
        SolveQuadraticNnls(q.A, q.b, x, fixed, options.nnls, interruption);
    std::vector<double> trial = fit.Weights(solved.x);
    error = fit.SelectError(trial);
    if (error <= options.max_error_growth * before || attempt >= options.max_retries || count == 1)
      return trial;
    count = std::max<std::size_t>(1, count / 2);
  }
}

// The springs, choosing errors and smallest eigenvalues of candidate models (path points, fits).
struct Candidates {
  std::vector<int> springs;
  std::vector<double> errors, lambdas;
};
template <typename Model>
Candidates CandidatesOf(const std::vector<Model>& models) {
  Candidates c;
  for (const Model& m : models) {
    c.springs.push_back(m.springs);
    c.errors.push_back(m.select_error);
    c.lambdas.push_back(m.lambda_min);
  }
  return c;
}

// The path's returned point: within a spring budget the best model within it; else (or when
// none is) the fewest springs within the tolerance of the best choosing error. Points that
// leave a mode soft are passed over for one that does not, nearly as good.
int ChoosePathPoint(const std::vector<ResponseFitResult::Point>& path,
                    const ResponseFitOptions& options) {
  const auto [springs, errors, lambdas] = CandidatesOf(path);
  // (Within a budget when no point is a model that meets it: the choice without a budget, and
  // the verdict says the budget was not met, engine/identification/verdict.h, rather than
  // returning a mechanism that meets it.)
  if (const auto within = BestWithinBudget(springs, errors, lambdas, options))
    return static_cast<int>(*within);
  const std::vector<double> score = PreferSupported(errors, lambdas, options);
  const double best = *std::min_element(score.begin(), score.end());
  int chosen = 0;
  for (std::size_t i = 0; i < path.size(); ++i) {
    if (score[i] <= (1.0 + options.tolerance) * best &&
        path[i].springs <= path[static_cast<std::size_t>(chosen)].springs)
      chosen = static_cast<int>(i);
  }
  return chosen;
}

// The dense fit's sparsity path from `x` (choosing error `error`) down, until the choosing error
// passes stop_error_factor times its best (below the budget, when there is one); fills r.path,
// r.chosen and the chosen point's errors, and returns its weights.
std::vector<double> SparsityPath(const Fit& fit, const ScaledQuadratic& q, const Vector& x,
                                 double error, const ResponseFitOptions& options,
                                 Interruption* interruption, const Tell& tell,
                                 ResponseFitResult& r) {
  std::vector<std::vector<double>> point_weights;
  std::vector<double> weights = fit.Weights(x);
  double best_on_path = kNoModel;
  for (int point = 0; point < options.max_path_points; ++point) {
    r.path.push_back({PresentSprings(weights), error, fit.LambdaMin(weights)});
    point_weights.push_back(weights);
    best_on_path = std::min(best_on_path, error);
    tell("probe_path", best_on_path);
    const bool within_budget =
        options.max_springs == 0 || r.path.back().springs <= options.max_springs;
    if (within_budget && error > options.stop_error_factor * best_on_path) break;
    std::optional<std::vector<double>> next =
        PrunePoint(fit, q, fit.Scaled(weights), options, interruption, error);
    if (!next) break;
    weights = std::move(*next);
  }
  r.chosen = ChoosePathPoint(r.path, options);
  const ResponseFitResult::Point& chosen = r.path[static_cast<std::size_t>(r.chosen)];
  r.select_error = chosen.select_error;
  r.lambda_min = chosen.lambda_min;
  return point_weights[static_cast<std::size_t>(r.chosen)];
}

// The dense fit's Gauss-Newton on the exact error over the springs of `weights` only (its Gram
// matrix on them alone: a fraction of the first-order one). Each step is kept when it lowers the
// fitted objective; the iterate returned is the one that does best on the choosing probes
// (early stopping), among those that support every mode when the start does. The steps end
// after three without a better choosing error. Sets r.weights and the returned iterate's
// errors.
void GaussNewton(Fit& fit, std::vector<double> weights, const ResponseFitOptions& options,
                 Interruption* interruption, const Tell& tell, ResponseFitResult& r) {
  std::vector<int> present;
  for (std::size_t g = 0; g < weights.size(); ++g)
    if (weights[g] > 0.0) present.push_back(static_cast<int>(g));
  const GeneSprings kept = Subset(fit.springs(), present);
  const auto on_kept = [&](const Vector& full) {
    Vector v(static_cast<Eigen::Index>(present.size()));
    for (std::size_t i = 0; i < present.size(); ++i)
      v[static_cast<Eigen::Index>(i)] = full[present[i]];
    return v;
  };
  const Vector kept_scale = on_kept(fit.scale());
  const Vector kept_prior = on_kept(fit.prior_scaled());
  double objective = fit.Objective(weights, r.regularization);
  std::vector<std::vector<double>> iterates{weights};
  std::vector<double> iterate_errors{r.select_error}, iterate_lambdas{r.lambda_min};
  int since_best = 0;
  for (int step = 0; step < options.gauss_newton_steps && since_best < 3; ++step) {
    Gram newton;
    if (!fit.GaussNewtonGram(weights, kept, newton)) break;
    const ScaledQuadratic qn =
        Scaled(newton, kept_scale, r.regularization, kept_prior, fit.scale().size());
    const Vector x0 = fit.Scaled(weights);
    const QuadraticNnlsResult solved =
        SolveQuadraticNnls(qn.A, qn.b, on_kept(x0), {}, options.nnls, interruption);
    Vector x1 = x0;
    for (std::size_t i = 0; i < present.size(); ++i)
      x1[present[i]] = solved.x[static_cast<Eigen::Index>(i)];
    bool accepted = false;
    for (int halving = 0; halving < 4 && !accepted; ++halving) {
      const double t = std::ldexp(1.0, -halving);
      const std::vector<double> trial = fit.Weights(x0 + t * (x1 - x0));
      if (PresentSprings(trial) == 0) continue;
      const double value = fit.Objective(trial, r.regularization);
      if (!(value < objective)) continue;
      weights = trial;
      objective = value;
      accepted = true;
      ++since_best;
      const double error = fit.SelectError(trial);
      iterates.push_back(weights);
      iterate_errors.push_back(error);
      iterate_lambdas.push_back(fit.LambdaMin(trial));
      if (error <
          *std::min_element(iterate_errors.begin(), iterate_errors.end() - 1) * (1.0 - 1e-3))
        since_best = 0;
    }
    tell("probe_refine", *std::min_element(iterate_errors.begin(), iterate_errors.end()));
    if (!accepted) break;
  }
  const std::vector<double> score = PreferSupported(iterate_errors, iterate_lambdas, options);
  const auto returned =
      static_cast<std::size_t>(std::min_element(score.begin(), score.end()) - score.begin());
  r.gauss_newton_accepted = static_cast<int>(returned);
  r.select_error = iterate_errors[returned];
  r.lambda_min = iterate_lambdas[returned];
  r.weights = iterates[returned];
}

// Step 2 with a Gram matrix, the dense fit (the genes up to dense_max_genes).
ResponseFitResult FitDense(const Problem& problem, const ProbeBank& bank,
                           const SparseMatrix& reference_stiffness,
                           const std::vector<double>& prior, const ResponseFitOptions& options,
                           Interruption* interruption, const ResponseProgress& progress,
                           WorkerPool* pool) {
  const Tell tell = [&](const char* phase, double error) {
    if (progress) progress(phase, error);
  };
  Fit fit(problem, bank, reference_stiffness, prior, options, interruption, pool);
  ResponseFitResult r;
  auto lap = std::chrono::steady_clock::now();
  const auto seconds = [&lap] { return NextLap(lap); };
  const Gram gram = fit.FirstOrderGram();
  r.seconds_gram = seconds();
  const PathStart start = FirstOrderFits(fit, gram, options, interruption, tell, r);
  r.seconds_first_order = seconds();
  const ScaledQuadratic q =
      Scaled(gram, fit.scale(), r.regularization, fit.prior_scaled(), fit.scale().size());
  const std::vector<double> chosen =
      SparsityPath(fit, q, start.x, start.error, options, interruption, tell, r);
  r.seconds_path = seconds();
  GaussNewton(fit, chosen, options, interruption, tell, r);
  r.seconds_refine = seconds();
  return r;
}

ResponseFitResult FitOnBank(const Problem& problem, const ProbeBank& bank,
                            const SparseMatrix& reference_stiffness,
                            const std::vector<double>& prior, const ResponseFitOptions& options,
                            Interruption* interruption, const ResponseProgress& progress,
                            WorkerPool* pool) {
  if (problem.gene_count() > options.dense_max_genes)
    return FitResponseMatrixFree(problem, bank, reference_stiffness, prior, options, interruption,
                                 progress, pool);
  return FitDense(problem, bank, reference_stiffness, prior, options, interruption, progress, pool);
}

// The fit (a soft-mode round, or the lift) returned: with a spring budget the best within it,
// as on the path; else the best on the choosing probes, a model that holds every mode preferred.
std::size_t ChooseRound(const std::vector<ResponseFitResult::SoftModeRound>& path,
                        const ResponseFitOptions& options) {
  const auto [springs, errors, lambdas] = CandidatesOf(path);
  if (const auto within = BestWithinBudget(springs, errors, lambdas, options)) return *within;
  const std::vector<double> score = PreferSupported(errors, lambdas, options);
  return static_cast<std::size_t>(std::min_element(score.begin(), score.end()) - score.begin());
}

}  // namespace

ResponseFitResult FitResponse(const Problem& problem, const ProbeBank& bank,
                              const SparseMatrix& reference_stiffness,
                              const std::vector<double>& prior, const ResponseFitOptions& options,
                              Interruption* interruption, const ResponseProgress& progress,
                              WorkerPool* pool) {
  options.Validate();
  std::vector<ResponseFitResult> rounds{
      FitOnBank(problem, bank, reference_stiffness, prior, options, interruption, progress, pool)};
  // 5. Soft modes: while the model leaves a mode of a user support below min_lambda, the load
  // along that mode joins the fitted probes and the fit runs again. The choosing probes are the
  // same in every round, so the rounds' models compare as the points of one path.
  std::vector<int> mode_probes;  // per refit, in its fit
  const int d = problem.dimension();
  // The reference factorised on each user support: the soft modes' and the lift's pencils.
  std::vector<std::pair<int, SupportSystem>> user;
  const auto user_supports = [&]() -> const std::vector<std::pair<int, SupportSystem>>& {
    if (user.empty()) {
      for (std::size_t s = 0; s < bank.supports.size(); ++s) {
        if (!bank.supports[s].user) continue;
        user.emplace_back(static_cast<int>(s), SupportSystem(d, bank.supports[s].constrained));
        user.back().second.Factorize(reference_stiffness);
      }
    }
    return user;
  };
  if (rounds.back().lambda_min < options.min_lambda && options.soft_mode_rounds > 0) {
    ProbeBank augmented = bank;
    for (int round = 0; round < options.soft_mode_rounds; ++round) {
      if (interruption && interruption->Check()) throw Interrupted();
      const SparseMatrix model = SpringRestStiffness(problem, rounds.back().weights);
      int added = 0;
      for (const auto& [s, reference] : user_supports()) {
        for (const SoftMode& mode :
             SoftModes(model, reference, options.min_lambda, options.soft_modes_per_round,
                       kLanczosIterations, interruption)) {
          AddSoftModeProbe(augmented, s, mode.shape, reference_stiffness, d);
          ++added;
        }
      }
      if (added == 0) break;
      mode_probes.push_back((mode_probes.empty() ? 0 : mode_probes.back()) + added);
      // (A whole fit again: started from the last model at its strength, the matrix-free fit's
      // steps lowered the fitted error and raised the choosing one on fem-block-3d, and the
      // soft modes stayed; its continuation from the prior is what lifts them.)
      rounds.push_back(FitOnBank(problem, augmented, reference_stiffness, prior, options,
                                 interruption, progress, pool));
      if (rounds.back().lambda_min >= options.min_lambda) break;
    }
  }
  std::vector<ResponseFitResult::SoftModeRound> path;
  for (std::size_t i = 0; i < rounds.size(); ++i) {
    const ResponseFitResult& r = rounds[i];
    path.push_back({i == 0 ? 0 : mode_probes[i - 1], PresentSprings(r.weights), r.select_error,
                    r.lambda_min, false});
  }
  std::size_t chosen = ChooseRound(path, options);
  // 6. The mode lift of the model chosen, when it leaves a mode soft: one more candidate.
  if (options.lift_soft_modes && path[chosen].lambda_min < options.min_lambda &&
      path[chosen].select_error < kNoModel) {
    if (progress) progress("probe_lift", path[chosen].select_error);
    ResponseFitResult lifted = rounds[chosen];
    lifted.weights = BoundSpread(LiftSoftModes(problem, lifted.weights, PriorScale(prior),
                                               user_supports(), options.lift, interruption)
                                     .weights,
                                 options.max_spread);
    const SparseMatrix model = SpringRestStiffness(problem, lifted.weights);
    lifted.select_error = ChoosingError(bank, model, interruption);
    lifted.lambda_min = kNoModel;
    for (const auto& [s, reference] : user_supports())
      lifted.lambda_min = std::min(
          lifted.lambda_min,
          SmallestGeneralizedEigenvalue(model, reference, kLanczosIterations, interruption));
    path.push_back(
        {0, PresentSprings(lifted.weights), lifted.select_error, lifted.lambda_min, true});
    rounds.push_back(std::move(lifted));
    chosen = ChooseRound(path, options);
  }
  ResponseFitResult r = std::move(rounds[chosen]);
  r.soft_mode_rounds = std::move(path);
  r.soft_mode_chosen = static_cast<int>(chosen);
  return r;
}

}  // namespace springfit::response
