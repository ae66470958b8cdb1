#include "engine/probe_fit/matrix_free_fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <optional>

#include "engine/fit/gauss_newton.h"
#include "engine/fit/pruning_path.h"
#include "engine/genome/gene_weights.h"
#include "engine/probe_fit/linearized_response.h"
#include "engine/probe_fit/mode_cuts.h"
#include "engine/probe_fit/model_chooser.h"
#include "engine/probe_fit/nonlinear_response.h"
#include "engine/probe_fit/probe_objective.h"
#include "engine/runtime/wall_clock.h"

namespace springfit::response {
namespace {

// What the driver descends and chooses by where it is not the rest-linear probe objective (the
// nonlinear stage's).
struct FitStage {
  // The objective's operators, made afresh for each point (unset: LinearizedResponse).
  std::function<std::unique_ptr<SpringSensitivities>(const ProbeObjective&, const GeneSprings&)>
      linearise;
  // A model's choosing error (unset: ProbeObjective::SelectError, rest-linear).
  std::function<double(const std::vector<double>& weights)> choosing_error;
  // Springs absent from the start stay out.
  bool freeze_absent = false;
  // The phase its progress reports.
  const char* phase = "probe_fit";
};

// The fit's state: the objective, and every accepted iterate with its strength, choosing error
// and smallest eigenvalue.
class MatrixFreeFit {
 public:
  MatrixFreeFit(const Problem& problem, const ProbeBank& bank,
                const SparseMatrix& reference_stiffness, const std::vector<double>& prior,
                const ResponseFitOptions& options, Interruption* interruption,
                const ResponseProgress& progress, WorkerPool* pool, FitStage stage = {})
      : objective_(problem, bank, reference_stiffness, prior, options, interruption),
        stage_(std::move(stage)),
        springs_(GeneSpringsOf(problem)),
        cuts_(options.hold, objective_.scale()),
        genes_(static_cast<double>(problem.gene_count())),
        options_(options),
        interruption_(interruption),
        progress_(progress),
        pool_(pool) {}

  struct Iterate {
    std::vector<double> weights;
    double regularization = 0.0;
    double select_error = kNoModel;
    double lambda_min = 0.0;
    int step = 0;
  };
  const std::vector<Iterate>& iterates() const { return iterates_; }

  // The continuation from the prior: `steps_per_strength` steps at every strength, strongest
  // first, until `continuation_patience` successive strengths each end worse on the choosing
  // probes than the best before them; records each strength's model in `r`.
  void Continuation(ResponseFitResult& r) {
    std::vector<double> weights = objective_.Weights(objective_.prior_scaled());
    std::unique_ptr<SpringSensitivities> at = Linearisation();
    const bool held = at->At(weights);
    Judge(weights, options_.regularizations.front(), 0, held ? at.get() : nullptr);
    if (!held) return;
    std::vector<double> strengths = options_.regularizations;
    std::sort(strengths.begin(), strengths.end(), std::greater<>());
    // (The nonlinear stage keeps the rest-linear fit's topology: absent springs stay out.)
    std::vector<bool> out(weights.size(), false);
    if (stage_.freeze_absent)
      for (std::size_t g = 0; g < weights.size(); ++g) out[g] = !(weights[g] > 0.0);
    int worse = 0;
    for (double strength : strengths) {
      double best = kNoModel;
      for (const Iterate& i : iterates_) best = std::min(best, i.select_error);
      Descend(weights, at, strength, out);
      // The model at this strength: its last accepted step's, or the one it started from when
      // none was accepted.
      r.regularizations.push_back(strength);
      r.regularization_select_errors.push_back(iterates_.back().select_error);
      r.regularization_lambda_min.push_back(iterates_.back().lambda_min);
      worse = iterates_.back().select_error < best ? 0 : worse + 1;
      if (options_.continuation_patience > 0 && worse >= options_.continuation_patience) break;
    }
  }

  // A spring budget: two sparsity paths down to it, at the strength of iterate `chosen`, one
  // from that iterate and one from the closed-form baseline's springs (the mesh edges) refitted
  // alone, as the fit's many springs stand in for each other in ways a path from them may not
  // undo. Returns the best iterate within the budget, or nothing when none is a model.
  std::optional<std::size_t> WithinBudget(std::size_t chosen) {
    // (A model held on a support has at least a spring per free degree of freedom there: a
    // budget below that is met by no model, and the paths would only try mechanisms.)
    for (std::size_t s : objective_.fitted_supports())
      if (options_.max_springs < objective_.reference()[s].free_dofs()) return std::nullopt;
    const double regularization = iterates_[chosen].regularization;
    BudgetPath(iterates_[chosen].weights, regularization, false);
    BudgetPath(objective_.Weights(objective_.prior_scaled()), regularization, true);
    return BestWithinBudget();
  }

  // One path from `weights` down to the spring budget (`refit`: its springs refitted first),
  // the one pruning path (engine/fit/pruning_path.h) with the saliency 1/2 x_e^2 (J^T J)_ee at
  // the current model, `prune_fraction` of the present springs at a time (rounded up), each
  // removal followed by the Gauss-Newton steps of the strength on the springs left; a spring
  // once out stays out. (A removal that leaves a mechanism is retried with half as many
  // springs; a single spring whose removal leaves one is kept for good: the saliency does not
  // see that a soft spring alone holds a node.)
  void BudgetPath(std::vector<double> weights, double regularization, bool refit) {
    std::unique_ptr<SpringSensitivities> at = Linearisation();
    if (!at->At(weights)) return;
    BudgetPruning model(*this, std::move(weights), std::move(at), regularization);
    if (refit) {
      Judge(model.weights(), regularization, step_count_, &model.at());
      model.Descend();
    }
    PruningOptions pruning;
    pruning.prune_fraction = options_.prune_fraction;
    pruning.round_up = true;
    PruneModel(model, options_.max_springs, pruning);
  }

  // The budget path's model: the current weights and their linearisation.
  class BudgetPruning : public PrunableModel {
   public:
    BudgetPruning(MatrixFreeFit& fit, std::vector<double> weights,
                  std::unique_ptr<SpringSensitivities> at, double regularization)
        : fit_(fit),
          weights_(std::move(weights)),
          at_(std::move(at)),
          regularization_(regularization),
          removed_(weights_.size(), false) {}

    int PresentSprings() const override { return springfit::PresentSprings(weights_); }
    // (Kept until the model changes: a failed removal asks again, and each estimate costs
    // diagonal_samples solves per support.)
    std::vector<int> BySaliency() const override {
      if (!order_) order_ = fit_.BySaliency(weights_, *at_);
      return *order_;
    }
    // The trial without `genes` linearised (kInfeasible when it has no model on some fitted
    // support), then judged and refitted.
    Removal Remove(const std::vector<int>& genes, bool /*may_refuse*/) override {
      ThrowIfInterrupted(fit_.interruption_);  // (each attempt factorises every fitted support)
      std::vector<double> trial = weights_;
      for (int g : genes) trial[static_cast<std::size_t>(g)] = 0.0;
      std::unique_ptr<SpringSensitivities> next = fit_.Linearisation();
      if (!next->At(trial)) return Removal::kInfeasible;
      weights_ = std::move(trial);
      at_ = std::move(next);
      order_.reset();
      fit_.Judge(weights_, regularization_, fit_.step_count_, at_.get());
      if (fit_.progress_) fit_.progress_("probe_path", fit_.iterates_.back().select_error);
      Descend();
      return Removal::kAccepted;
    }
    // The strength's steps on the springs present (those out stay out).
    void Descend() {
      for (std::size_t g = 0; g < weights_.size(); ++g)
        removed_[g] = removed_[g] || !(weights_[g] > 0.0);
      fit_.Descend(weights_, at_, regularization_, removed_);
      order_.reset();
    }
    const std::vector<double>& weights() const { return weights_; }
    const SpringSensitivities& at() const { return *at_; }

   private:
    MatrixFreeFit& fit_;
    std::vector<double> weights_;
    std::unique_ptr<SpringSensitivities> at_;
    double regularization_;
    std::vector<bool> removed_;
    mutable std::optional<std::vector<int>> order_;  // BySaliency of the current model
  };

  // The best iterate within the spring budget that is a model; nothing when none is.
  std::optional<std::size_t> BestWithinBudget() const {
    return ModelChooser(options_).BestWithinBudget(Candidates());
  }

  // The best iterate from `from` on (ModelChooser::Best).
  std::size_t BestOf(std::size_t from) const {
    return ModelChooser(options_).Best(Candidates(), from);
  }

 private:
  // The iterates as the chooser sees them.
  std::vector<CandidateModel> Candidates() const {
    std::vector<CandidateModel> candidates;
    for (const Iterate& it : iterates_)
      candidates.push_back({PresentSprings(it.weights), it.select_error, it.lambda_min});
    return candidates;
  }

  // The present springs of `weights`, least salient first (1/2 x_e^2 (J^T J)_ee, `at` its
  // linearisation; ties by gene).
  std::vector<int> BySaliency(const std::vector<double>& weights,
                              const SpringSensitivities& at) const {
    const Vector x = objective_.Scaled(weights);
    const Vector diagonal = at.NormalDiagonal(options_.diagonal_samples, options_.probes.seed);
    std::vector<std::pair<double, int>> saliency;
    for (int e = 0; e < x.size(); ++e)
      if (x[e] > 0.0) saliency.emplace_back(0.5 * x[e] * x[e] * diagonal[e], e);
    std::sort(saliency.begin(), saliency.end());
    std::vector<int> order;
    for (const auto& [value, e] : saliency) order.push_back(e);
    return order;
  }

  std::unique_ptr<SpringSensitivities> Linearisation() const {
    if (stage_.linearise) return stage_.linearise(objective_, springs_);
    return std::make_unique<LinearizedResponse>(objective_, springs_, interruption_, pool_);
  }

  // Records `weights` as an iterate; `at`, when given, is its linearisation, whose
  // factorisations the judgements reuse.
  void Judge(const std::vector<double>& weights, double regularization, int step,
             const SpringSensitivities* at) {
    const FactorizedOn factorized = at ? at->Factorized() : FactorizedOn{};
    std::vector<ProbeObjective::SupportMode> soft;
    const double lambda_min = cuts_.enabled() ? objective_.LambdaMinAndSoftModes(
                                                    weights, factorized, cuts_.options().target,
                                                    cuts_.options().modes_per_support, soft)
                                              : objective_.LambdaMin(weights, factorized);
    iterates_.push_back({weights, regularization,
                         stage_.choosing_error ? stage_.choosing_error(weights)
                                               : objective_.SelectError(weights, factorized),
                         lambda_min, step});
    // A cut for each mode the model leaves below the held target on a user support: the steps
    // after it keep away from those modes.
    for (const ProbeObjective::SupportMode& soft_mode : soft)
      cuts_.Add(springs_, soft_mode.mode, objective_.reference()[soft_mode.support]);
    double best = kNoModel;
    for (const Iterate& i : iterates_) best = std::min(best, i.select_error);
    if (progress_) progress_(stage_.phase, best);
  }

  // The fitted objective at `weights` (`at` its linearisation): the probes' error, the Tikhonov
  // pull and the held modes' penalty.
  double Phi(const std::vector<double>& weights, const SpringSensitivities& at,
             double regularization) const {
    return at.ResidualNorm2() + objective_.Regularization(weights, regularization) +
           cuts_.Penalty(objective_.Scaled(weights));
  }

  // A model of the fit as the core's point (engine/fit/gauss_newton.h): the scaled stiffness
  // x, its linearisation, the strength's Tikhonov pull and the held modes' penalty (read at
  // every call: a judgement may add cuts).
  class Point : public GaussNewtonPoint {
   public:
    Point(const MatrixFreeFit& fit, std::vector<double> weights,
          std::unique_ptr<SpringSensitivities> at, double regularization,
          const std::vector<bool>& removed)
        : fit_(fit),
          weights_(std::move(weights)),
          x_(fit.objective_.Scaled(weights_)),
          at_(std::move(at)),
          regularization_(regularization),
          rho_(regularization / fit.genes_),
          removed_(removed) {}

    double Value() const override { return fit_.Phi(weights_, *at_, regularization_); }
    Vector Gradient() const override {
      return at_->Gradient() + rho_ * (x_ - fit_.objective_.prior_scaled()) +
             fit_.cuts_.HalfGradient(x_);
    }
    Vector NormalProduct(const Vector& v) const override {
      return at_->NormalProduct(v) + rho_ * v + fit_.cuts_.HalfHessianProduct(x_, v);
    }
    Vector NormalDiagonal() const override {
      Vector diagonal =
          at_->NormalDiagonal(fit_.options_.diagonal_samples, fit_.options_.probes.seed);
      diagonal.array() += rho_;
      return diagonal + fit_.cuts_.HalfHessianDiagonal(x_);
    }
    // Springs removed stay out; one at 0 stays there while the gradient pushes it below.
    std::vector<bool> Free(const Vector& gradient) const override {
      std::vector<bool> free(static_cast<std::size_t>(x_.size()));
      for (Eigen::Index e = 0; e < x_.size(); ++e)
        free[static_cast<std::size_t>(e)] =
            !removed_[static_cast<std::size_t>(e)] && !(x_[e] <= 0.0 && gradient[e] > 0.0);
      return free;
    }
    Vector Taken(const Vector& d, double t) const override {
      return (x_ + t * d).cwiseMax(0.0) - x_;
    }
    // max(x + t d, 0), with the dust out (ProbeObjective::Weights).
    std::unique_ptr<GaussNewtonPoint> Trial(const Vector& d, double t) const override {
      std::vector<double> trial = fit_.objective_.Weights((x_ + t * d).cwiseMax(0.0));
      if (PresentSprings(trial) == 0) return nullptr;
      std::unique_ptr<SpringSensitivities> next = fit_.Linearisation();
      if (!next->At(trial)) return nullptr;
      return std::make_unique<Point>(fit_, std::move(trial), std::move(next), regularization_,
                                     removed_);
    }

    void Idle() override { at_->Idle(); }

    const std::vector<double>& weights() const { return weights_; }
    const SpringSensitivities& at() const { return *at_; }
    // Hands the model and its linearisation back (the point is spent).
    void Release(std::vector<double>& weights, std::unique_ptr<SpringSensitivities>& at) {
      weights = std::move(weights_);
      at = std::move(at_);
    }

   private:
    const MatrixFreeFit& fit_;
    std::vector<double> weights_;
    Vector x_;
    std::unique_ptr<SpringSensitivities> at_;
    double regularization_, rho_;
    const std::vector<bool>& removed_;
  };

  // The core's steps at one strength from `weights`, `at` its linearisation (springs with
  // `removed` set stay out); each accepted step is judged, and `weights` and `at` follow it.
  void Descend(std::vector<double>& weights, std::unique_ptr<SpringSensitivities>& at,
               double regularization, const std::vector<bool>& removed) {
    std::unique_ptr<GaussNewtonPoint> point =
        std::make_unique<Point>(*this, std::move(weights), std::move(at), regularization, removed);
    GaussNewtonOptions descent;
    descent.max_steps = options_.steps_per_strength;
    descent.cg_iterations = options_.cg_iterations;
    descent.cg_tolerance = options_.cg_tolerance;
    DescendGaussNewton(
        point, descent,
        [&](const GaussNewtonPoint& accepted) {
          const auto& p = static_cast<const Point&>(accepted);
          Judge(p.weights(), regularization, ++step_count_, &p.at());
        },
        interruption_);
    static_cast<Point&>(*point).Release(weights, at);
  }

  const ProbeObjective objective_;
  const FitStage stage_;
  const GeneSprings springs_;
  ModeCuts cuts_;
  const double genes_;
  const ResponseFitOptions& options_;
  Interruption* interruption_;
  const ResponseProgress& progress_;
  WorkerPool* pool_;
  std::vector<Iterate> iterates_;
  int step_count_ = 0;
};

}  // namespace

ResponseFitResult FitResponseMatrixFree(const Problem& problem, const ProbeBank& bank,
                                        const SparseMatrix& reference_stiffness,
                                        const std::vector<double>& prior,
                                        const ResponseFitOptions& options,
                                        Interruption* interruption,
                                        const ResponseProgress& progress, WorkerPool* pool) {
  const auto started = std::chrono::steady_clock::now();
  const auto seconds = [&started] { return SecondsSince(started); };
  MatrixFreeFit fit(problem, bank, reference_stiffness, prior, options, interruption, progress,
                    pool);
  ResponseFitResult r;
  r.method = "matrix-free";
  fit.Continuation(r);
  r.seconds_continuation = seconds();

  std::size_t chosen = fit.BestOf(0);
  const auto point = [&](std::size_t i) {
    const MatrixFreeFit::Iterate& it = fit.iterates()[i];
    return ResponseFitResult::Point{PresentSprings(it.weights), it.select_error, it.lambda_min};
  };
  r.path.push_back(point(chosen));
  if (options.max_springs > 0 && r.path.back().springs > options.max_springs) {
    if (const std::optional<std::size_t> within = fit.WithinBudget(chosen)) {
      r.path.push_back(point(*within));
      if (r.path.back().select_error < kNoModel && r.path.back().lambda_min > 0.0) {
        chosen = *within;
        r.chosen = 1;
      }
    }
  }
  const MatrixFreeFit::Iterate& returned = fit.iterates()[chosen];
  r.weights = returned.weights;
  r.regularization = returned.regularization;
  r.select_error = returned.select_error;
  r.lambda_min = returned.lambda_min;
  r.gauss_newton_accepted = returned.step;
  r.seconds_budget = seconds() - r.seconds_continuation;
  return r;
}

NonlinearFitResult FitNonlinearResponse(
    const Problem& problem, const ProbeBank& bank, const SparseMatrix& reference_stiffness,
    const std::vector<double>& start, const ResponseFitOptions& options,
    const NonlinearFitOptions& nonlinear, const std::vector<double>* baseline,
    Interruption* interruption, const ResponseProgress& progress, WorkerPool* pool) {
  const auto started = std::chrono::steady_clock::now();
  nonlinear.Validate();
  NonlinearCases cases(problem, bank, FitWeights(bank, options.probes), nonlinear, interruption,
                       pool);
  std::vector<double> start_errors;
  {
    const GeneSprings springs = GeneSpringsOf(problem);
    NonlinearResponse at_start(cases, springs, PriorScale(start), interruption, pool);
    at_start.At(start);
    start_errors = at_start.CaseErrors();
  }
  NonlinearFitResult r;
  r.fitted_left_out = cases.StartFrom(start_errors);
  r.left_for_memory = cases.LeftForMemory();
  r.case_bytes = cases.CaseBytes();
  r.max_bytes = nonlinear.max_bytes;
  r.amplitudes = nonlinear.amplitudes;
  r.fitted_cases = static_cast<int>(cases.fitted().size());
  r.choosing_cases = static_cast<int>(cases.choosing().size());
  // The stage's options: its strengths and steps; the topology is the rest-linear fit's.
  ResponseFitOptions stage_options = options;
  stage_options.regularizations = nonlinear.regularizations;
  stage_options.steps_per_strength = nonlinear.steps_per_strength;
  stage_options.max_springs = 0;
  FitStage stage;
  stage.linearise = [&](const ProbeObjective& objective, const GeneSprings& springs) {
    return std::make_unique<NonlinearResponse>(cases, springs, objective.scale(), interruption,
                                               pool);
  };
  stage.choosing_error = [&](const std::vector<double>& weights) {
    return cases.ChoosingError(weights);
  };
  stage.freeze_absent = true;
  stage.phase = "nonlinear_fit";
  MatrixFreeFit fit(problem, bank, reference_stiffness, start, stage_options, interruption,
                    progress, pool, std::move(stage));
  ResponseFitResult ignored;
  if (r.fitted_cases > 0 && r.choosing_cases > 0) fit.Continuation(ignored);
  // (Without cases the start stands: its iterate alone is judged.)
  const std::size_t chosen = fit.iterates().empty() ? 0 : fit.BestOf(0);
  r.start_choosing_error = cases.ChoosingError(start, &r.start_failed);
  // (The first iterate is the start with the fit's dust and spread bounds applied, which can
  // judge worse than the start itself: the start stands unless the chosen iterate beats it.)
  if (fit.iterates().empty() || chosen == 0 ||
      !(fit.iterates()[chosen].select_error < r.start_choosing_error)) {
    r.weights = start;
    r.choosing_error = r.start_choosing_error;
    r.failed = r.start_failed;
  } else {
    const MatrixFreeFit::Iterate& it = fit.iterates()[chosen];
    r.weights = it.weights;
    r.regularization = it.regularization;
    r.steps = it.step;
    r.choosing_error = cases.ChoosingError(r.weights, &r.failed);
  }
  if (baseline) r.baseline_choosing_error = cases.ChoosingError(*baseline);
  r.seconds = SecondsSince(started);
  return r;
}

}  // namespace springfit::response
