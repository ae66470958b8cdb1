#include "engine/fit/stiffness_fit.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <random>

#include "engine/fit/gauss_newton.h"
#include "engine/model/equilibrium.h"
#include "engine/problem/force_balance.h"
#include "engine/runtime/options_check.h"

namespace springfit {
namespace {

// Below this normalised error the fit is exact (an MSS reference): nothing is left to fit.
constexpr double kExactError = 1e-24;
// The saliency probes' signs.
constexpr std::uint64_t kSaliencySeed = 20031116;
// Linear solves: passes of iterative refinement at most, and the gradient, relative to the
// load's, at which they stop.
constexpr int kRefinementPasses = 4;
constexpr double kRefinedResidual = 1e-14;
// The fraction of itself a weight keeps, at least, in a step stopped short of the bounds.
constexpr double kShortFraction = 0.1;

// The model's response at one set of weights: equilibria, tangents factorised, residuals.
class ResponseState {
 public:
  ResponseState(const Problem& problem, std::vector<bool> cases, const FitContext& context)
      : problem_(problem),
        cases_(std::move(cases)),
        interruption_(context.interruption),
        pool_(context.pool) {
    Interruption* interruption = context.interruption;
    if (cases_.empty()) cases_.assign(problem.load_cases().size(), true);
    // The linear response's tangent is the rest stiffness, the same for every case with the
    // same free nodes: one solver (one factorisation) per set of free nodes. The nonlinear
    // one's depends on the case's equilibrium: one solver per case.
    linear_ = problem.response() == Response::kLinear;
    const auto add_solver = [&](const FreeNodes& free) {
      solvers_.emplace_back(problem.candidates(), free, problem.solver_options());
      solvers_.back().set_interruption(interruption);
    };
    if (linear_) {
      for (const FreeNodes& free : problem.free_sets()) add_solver(free);
    }
    for (const PreparedLoadCase& lc : problem.load_cases()) {
      if (!linear_) add_solver(problem.free_sets()[lc.free_set]);
      solver_of_case_.push_back(linear_ ? lc.free_set : static_cast<int>(solvers_.size()) - 1);
      u_.push_back(lc.reference);  // warm start: the reference's equilibrium
    }
    Eigen::Index rows = 0;
    for (const PreparedLoadCase& lc : problem.load_cases()) {
      offset_.push_back(rows);
      rows += problem.dimension() * problem.free_sets()[lc.free_set].count;
    }
    offset_.push_back(rows);
    r_ = Vector::Zero(rows);  // a case left out keeps its rows at 0
    rest_ = Vector::Zero(problem.dimension() * problem.scene().node_count());
  }

  // sum over the fitted cases of |u^R|^2: the normaliser of their error.
  double ReferenceNorm2() const {
    double sum = 0.0;
    for (std::size_t k = 0; k < cases_.size(); ++k) {
      if (cases_[k]) sum += problem_.load_cases()[k].reference_norm2;
    }
    return sum;
  }

  // Solves every load case at `w` (warm-started from the last state) and factorises its
  // tangent. False when the model has no equilibrium (a mechanism, no convergence); the state
  // is then unusable until the next successful Evaluate. Throws Interrupted.
  bool Evaluate(const std::vector<double>& w) {
    const Problem& p = problem_;
    const ActiveSprings springs = p.SpringsOfWeights(w);
    // Stability first, once per set of free nodes (linear: the factorisation every case of the
    // set then solves with).
    std::vector<bool> checked(p.free_sets().size(), false);
    for (std::size_t k = 0; k < p.load_cases().size(); ++k) {
      const int set = p.load_cases()[k].free_set;
      if (!cases_[k] || checked[set]) continue;
      checked[set] = true;
      EquilibriumSolver& solver = solvers_[solver_of_case_[k]];
      // The mechanism verdict of every evaluation (engine/problem/cost.h). Linear: the
      // factorisation of the rest stiffness is the one every case of the set solves with, refined
      // to round-off (SolveLinear).
      if (solver.RestMechanismModes(springs) > 0) return false;
      if (linear_ && !solver.FactorizeTangent(springs, rest_)) return false;
    }
    std::vector<std::uint8_t> solved(p.load_cases().size(), 1);
    ForEachCase([&](std::size_t k) {
      solved[k] = linear_ ? SolveLinear(k, springs) : SolveNonlinear(k, springs);
    });
    for (std::size_t k = 0; k < p.load_cases().size(); ++k) {
      if (!cases_[k]) continue;
      if (!solved[k]) return false;
      const PreparedLoadCase& lc = p.load_cases()[k];
      const FreeNodes& free = p.free_sets()[lc.free_set];
      const int d = p.dimension();
      for (int i = 0; i < static_cast<int>(free.free_index.size()); ++i) {
        const int f = free.free_index[i];
        if (f >= 0)
          r_.segment(offset_[k] + d * f, d) =
              u_[k].segment(d * i, d) - lc.reference.segment(d * i, d);
      }
    }
    return true;
  }

  const Vector& residual() const { return r_; }
  const std::vector<Vector>& displacements() const { return u_; }
  std::vector<Vector>& displacements() { return u_; }
  std::int64_t solves() const { return solves_; }

  // y <- H^-1 y, block by load case.
  void ApplyInverseTangent(Vector& y) {
    ForEachCase([&](std::size_t k) {
      const Eigen::Index size = offset_[k + 1] - offset_[k];
      if (size == 0) return;
      Vector block = y.segment(offset_[k], size);
      solvers_[solver_of_case_[k]].SolveTangent(block);
      y.segment(offset_[k], size) = block;
    });
    // A left-out case has no tangent here: its rows of J are 0.
    for (std::size_t k = 0; k < cases_.size(); ++k) {
      if (!cases_[k]) y.segment(offset_[k], offset_[k + 1] - offset_[k]).setZero();
    }
    for (std::size_t k = 0; k < cases_.size(); ++k) solves_ += cases_[k] ? 1 : 0;
  }

 private:
  // body(k) for every fitted case, on the pool's threads when there is one (each case writes
  // only its own state; the linear cases of one set of free nodes share a factorisation,
  // which solves only read). Between the owner's waits the interruption is polled.
  void ForEachCase(const std::function<void(std::size_t)>& body) {
    std::vector<std::size_t> fitted;
    for (std::size_t k = 0; k < cases_.size(); ++k) {
      if (cases_[k]) fitted.push_back(k);
    }
    if (!pool_ || pool_->threads() <= 1 || fitted.size() <= 1) {
      for (std::size_t k : fitted) {
        if (interruption_ && interruption_->Check()) throw Interrupted();
        body(k);
      }
      return;
    }
    pool_->Run(
        static_cast<int>(fitted.size()), [&](int slot) { body(fitted[slot]); },
        [this] {
          if (interruption_) interruption_->Check();
        });
    if (interruption_ && interruption_->Check()) throw Interrupted();
  }

  // Linear: u = u_p - K^-1 g(u_p), g the energy's gradient with the free nodes at rest (one
  // Newton step is exact on the quadratic energy), with the set's factorisation. That
  // factorisation carries round-off of about eps x cond(K), so the step is repeated on the
  // remaining gradient (iterative refinement) until the gradient is at round-off of the load.
  bool SolveLinear(std::size_t k, const ActiveSprings& springs) {
    const PreparedLoadCase& lc = problem_.load_cases()[k];
    const FreeNodes& free = problem_.free_sets()[lc.free_set];
    EquilibriumSolver& solver = solvers_[solver_of_case_[k]];
    const int d = problem_.dimension();
    Vector& u = u_[k];
    u = lc.prescribed;  // zero on the free nodes
    Vector step;
    double load = 0.0, residual = 0.0;
    for (int pass = 0;; ++pass) {
      solver.EnergyAndGradient(springs, lc.force, u, &step, false, false);
      residual = step.lpNorm<Eigen::Infinity>();
      if (pass == 0) load = residual;
      if (!(residual > kRefinedResidual * load) || pass == kRefinementPasses) break;
      step = -step;
      solver.SolveTangent(step);
      for (int i = 0; i < static_cast<int>(free.free_index.size()); ++i) {
        const int f = free.free_index[i];
        if (f >= 0) u.segment(d * i, d) += step.segment(d * f, d);
      }
    }
    // A model so near a mechanism that refinement cannot balance the load has no usable
    // equilibrium: the solver's relative force tolerance, relative here to the load's gradient
    // (without the solver's round-off floor, so the fit can refuse a model at that edge which
    // the final evaluation would accept, never the reverse).
    return u.allFinite() && residual <= problem_.solver_options().relative_force_tolerance * load;
  }

  // Nonlinear: Newton from the last equilibrium, then the tangent there factorised.
  bool SolveNonlinear(std::size_t k, const ActiveSprings& springs) {
    const PreparedLoadCase& lc = problem_.load_cases()[k];
    EquilibriumSolver& solver = solvers_[solver_of_case_[k]];
    const EquilibriumSummary s = solver.Solve(springs, lc.force, lc.prescribed, u_[k]);
    if (s.termination == Termination::kInterrupted) throw Interrupted();
    return s.converged() && solver.FactorizeTangent(springs, u_[k]);
  }

  const Problem& problem_;
  std::vector<bool> cases_;
  Interruption* interruption_ = nullptr;
  WorkerPool* pool_ = nullptr;
  bool linear_ = false;
  std::vector<EquilibriumSolver> solvers_;
  std::vector<int> solver_of_case_;
  std::vector<Vector> u_;
  Vector rest_;  // all displacements 0: where the linear response's tangent is taken
  std::vector<Eigen::Index> offset_;
  Vector r_;
  std::int64_t solves_ = 0;
};

}  // namespace

GaussNewtonOptions NamedCaseDescent() {
  GaussNewtonOptions o;
  o.max_steps = 200;
  o.cg_iterations = 40;
  o.cg_tolerance = 1e-3;
  o.initial_radius = 1.0;
  o.max_radius = 1e3;
  o.relative_tolerance = 1e-6;
  return o;
}

void StiffnessFitOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  descent.Validate(check.Nested("descent"));
  check.Require(descent.initial_radius > 0.0, "descent.initial_radius", descent.initial_radius,
                "value > 0 (the named-case fit runs in a trust region)");
  check.Require(max_stiffness_ratio > 1.0 && std::isfinite(max_stiffness_ratio),
                "max_stiffness_ratio", max_stiffness_ratio, "1 < value < infinity");
  check.Require(scale_floor > 0.0 && scale_floor <= 1.0, "scale_floor", scale_floor,
                "0 < value <= 1");
  check.Require(saliency_probes >= 0, "saliency_probes", saliency_probes, "value >= 0");
  check.Require(upper_bound >= 0.0 && std::isfinite(upper_bound), "upper_bound", upper_bound,
                "0 <= value < infinity (0: from max_stiffness_ratio)");
  check.Require(regularization >= 0.0 && std::isfinite(regularization), "regularization",
                regularization, "0 <= value < infinity");
}

namespace {

// FitStiffness as an objective on the fitting core (gauss_newton.h): Phi = 1/2 |r|^2 + the
// regularisation, over the weights within [0, upper]. Two response states take turns: the
// current point's, and its trials' (each warm-started from the current equilibria), so that a
// trial that fails leaves the current point as it was.
class NamedCaseObjective {
 public:
  NamedCaseObjective(const Problem& problem, const std::vector<double>& start,
                     const FitScope& scope, const StiffnessFitOptions& options,
                     const FitContext& context)
      : problem_(problem),
        scope_(scope),
        options_(options),
        context_(context),
        genes_(problem.gene_count()) {
    states_.reserve(2);
    states_.emplace_back(problem, scope.cases, context);
    states_.emplace_back(problem, scope.cases, context);
    norm2_ = states_[0].ReferenceNorm2();
    start_ = start;
    start_.resize(static_cast<std::size_t>(genes_), 0.0);
    for (int g = 0; g < genes_; ++g) {
      if (!scope.usable[g] || !(start_[g] > 0.0)) start_[g] = 0.0;
    }
    // The upper bound: a spring this much stiffer than the stiffest at the start is rigid for
    // the data (a rigid limit, where the displacements no longer respond to it).
    upper_ = options.upper_bound > 0.0
                 ? options.upper_bound
                 : options.max_stiffness_ratio * *std::max_element(start_.begin(), start_.end());
  }

  StiffnessFitResult Run() {
    StiffnessFitResult result;
    result.weights = start_;
    std::unique_ptr<GaussNewtonPoint> point = Start();
    if (!point) {
      result.feasible = false;
      result.normalized_error = result.initial_normalized_error =
          std::numeric_limits<double>::infinity();
      return result;
    }
    result.initial_normalized_error = Error(*point);
    GaussNewtonOptions descent = options_.descent;
    descent.target_value = 0.5 * kExactError * norm2_;
    try {
      const GaussNewtonOutcome outcome = DescendGaussNewton(
          point, descent,
          [&](const GaussNewtonPoint& accepted) {
            const auto& p = static_cast<const Point&>(accepted);
            ++result.accepted;
            if (context_.on_step) context_.on_step(p.weights(), Error(p), result.accepted);
          },
          context_.interruption);
      result.iterations = outcome.steps;
      result.converged = outcome.converged;
    } catch (const springfit::Interrupted&) {
      result.interrupted = true;            // the point is the last accepted step's
      result.iterations = result.accepted;  // (at least: the refused steps are not counted)
    }
    const auto& last = static_cast<const Point&>(*point);
    if (Error(last) <= kExactError) result.converged = true;
    result.weights = last.weights();
    result.normalized_error = Error(last);
    if (!result.interrupted && options_.saliency_probes > 0) Saliency(last, result);
    result.solves = states_[0].solves() + states_[1].solves();
    return result;
  }

 private:
  // A set of weights with its equilibria solved in response state `state`.
  class Point : public GaussNewtonPoint {
   public:
    Point(NamedCaseObjective& fit, std::vector<double> weights, int state)
        : fit_(fit),
          weights_(std::move(weights)),
          state_(state),
          data_phi_(0.5 * fit.states_[state].residual().squaredNorm()) {
      // Weight g moves in units of s_g = max(w_g, scale_floor x the median weight): a step
      // changes each weight relative to itself, so it cannot take a spring to 0 in one stride
      // unless the model asks for it, and an absent spring enters at a typical stiffness.
      const double typical = MedianPositive(weights_);
      scale_.resize(fit.genes_);
      for (int g = 0; g < fit.genes_; ++g)
        scale_[g] = std::max(weights_[g], fit.options_.scale_floor * typical);
    }

    double Value() const override { return data_phi_ + fit_.Penalty(weights_); }
    // S (A^T H^-1 r + the regularisation's gradient): J^T r by the adjoint, one solve per case.
    Vector Gradient() const override {
      Vector t = fit_.states_[state_].residual();
      fit_.states_[state_].ApplyInverseTangent(t);
      Vector gradient = Balance().a.transpose() * t;
      for (int g = 0; g < fit_.genes_; ++g)
        gradient[g] += fit_.curvature_[g] * (weights_[g] - fit_.prior_[g]);
      return scale_.cwiseProduct(gradient);
    }
    // S J^T J S v plus the regularisation's curvature: two solves per case.
    Vector NormalProduct(const Vector& v) const override {
      const Vector sv = v.cwiseProduct(scale_);
      Vector t = Balance().a * sv;
      fit_.states_[state_].ApplyInverseTangent(t);  // J S v = H^-1 A S v
      fit_.states_[state_].ApplyInverseTangent(t);  // the adjoint: J^T y = A^T H^-1 y
      return scale_.cwiseProduct(Balance().a.transpose() * t + fit_.curvature_.cwiseProduct(sv));
    }
    // No preconditioner: an estimated Jacobi one steers the steps into springs the data barely
    // see, which then run to their bounds (docs/ARCHITECTURE.md, "The fitting core").
    Vector NormalDiagonal() const override { return Vector::Ones(fit_.genes_); }
    // Unusable genes stay at 0; a weight at a bound stays while the gradient pushes it past.
    std::vector<bool> Free(const Vector& gradient) const override {
      std::vector<bool> free(static_cast<std::size_t>(fit_.genes_));
      for (int g = 0; g < fit_.genes_; ++g)
        free[g] = fit_.scope_.usable[g] && !(weights_[g] == 0.0 && gradient[g] >= 0.0) &&
                  !(weights_[g] == fit_.upper_ && gradient[g] <= 0.0);
      return free;
    }
    Vector Taken(const Vector& d, double t) const override {
      const std::vector<double> moved = Moved(d, t);
      Vector taken(fit_.genes_);
      for (int g = 0; g < fit_.genes_; ++g) taken[g] = (moved[g] - weights_[g]) / scale_[g];
      return taken;
    }
    // Each weight the step takes below kShortFraction of itself kept at that fraction instead
    // (its own fraction-to-the-bound: one small spring does not shorten the whole step).
    Vector ShortOfBounds(const Vector& d) const override {
      Vector shorter = d;
      for (int g = 0; g < fit_.genes_; ++g)
        if (d[g] != 0.0 && weights_[g] + scale_[g] * d[g] < kShortFraction * weights_[g])
          shorter[g] = (kShortFraction - 1.0) * weights_[g] / scale_[g];
      return shorter;
    }
    // w + t S d within [0, upper], solved in the other state from this point's equilibria.
    std::unique_ptr<GaussNewtonPoint> Trial(const Vector& d, double t) const override {
      std::vector<double> trial = Moved(d, t);
      const int other = 1 - state_;
      fit_.states_[other].displacements() = fit_.states_[state_].displacements();
      if (!fit_.states_[other].Evaluate(trial)) return nullptr;
      return std::make_unique<Point>(fit_, std::move(trial), other);
    }

    // w + t S d within [0, upper] (a weight the step leaves alone stays exactly where it is).
    std::vector<double> Moved(const Vector& d, double t) const {
      std::vector<double> moved(weights_.size());
      for (int g = 0; g < fit_.genes_; ++g)
        moved[g] = d[g] == 0.0 ? weights_[g]
                               : std::clamp(weights_[g] + t * scale_[g] * d[g], 0.0, fit_.upper_);
      return moved;
    }

    const std::vector<double>& weights() const { return weights_; }
    double data_phi() const { return data_phi_; }
    int state() const { return state_; }
    // The force balance's columns at this point's equilibria (once: every product uses it).
    const ForceBalance& Balance() const {
      if (!balance_)
        balance_ = AssembleForceBalance(fit_.problem_, &fit_.states_[state_].displacements());
      return *balance_;
    }

   private:
    NamedCaseObjective& fit_;
    std::vector<double> weights_;
    int state_;
    double data_phi_;
    Vector scale_;
    mutable std::optional<ForceBalance> balance_;
  };

  double Error(const GaussNewtonPoint& point) const {
    return 2.0 * static_cast<const Point&>(point).data_phi() / norm2_;
  }

  // The start's equilibria (nullptr: it has none, and the fit ends infeasible) and the
  // regularisation: 1/2 mu sum_j ((w_j - p_j) / s_j)^2 over the usable genes (those held at 0
  // add a constant), mu scaled so that its E^2 is `regularization` x the mean square.
  std::unique_ptr<GaussNewtonPoint> Start() {
    if (!states_[0].Evaluate(start_)) return nullptr;
    prior_ = scope_.prior.empty() ? start_ : scope_.prior;
    prior_.resize(static_cast<std::size_t>(genes_), 0.0);
    const double mu = options_.regularization * norm2_ / std::max(genes_, 1);
    curvature_ = Vector::Zero(genes_);  // mu / s_j^2 on the usable genes
    if (mu > 0.0) {
      const double floor = options_.scale_floor * MedianPositive(prior_);
      for (int g = 0; g < genes_; ++g) {
        if (scope_.usable[g]) curvature_[g] = mu / std::pow(std::max(prior_[g], floor), 2);
      }
    }
    return std::make_unique<Point>(*this, start_, 0);
  }

  double Penalty(const std::vector<double>& w) const {
    double sum = 0.0;
    for (int g = 0; g < genes_; ++g) {
      if (curvature_[g] > 0.0) sum += curvature_[g] * (w[g] - prior_[g]) * (w[g] - prior_[g]);
    }
    return 0.5 * sum;
  }

  // Saliency (optimal brain damage, LeCun, Denker and Solla 1990): at an optimum the gradient
  // of a positive weight vanishes, so removing spring j raises f by about 1/2 w_j^2 |J e_j|^2.
  // The column norms are estimated from random-sign products J^T z (E[(J^T z)_j^2] =
  // |J e_j|^2): one solve per load case each, where the exact ones would cost one per gene.
  // The signs come from a fixed seed: deterministic.
  void Saliency(const Point& at, StiffnessFitResult& result) {
    ResponseState& state = states_[at.state()];
    const ForceBalance& balance = at.Balance();
    Vector column2 = Vector::Zero(genes_);
    Vector t(state.residual().size());
    std::mt19937_64 signs(kSaliencySeed);
    for (int probe = 0; probe < options_.saliency_probes; ++probe) {
      for (Eigen::Index row = 0; row < t.size(); ++row) t[row] = (signs() >> 63) ? 1.0 : -1.0;
      state.ApplyInverseTangent(t);
      column2 += (balance.a.transpose() * t).cwiseAbs2();
    }
    result.importance.assign(static_cast<std::size_t>(genes_), 0.0);
    const std::vector<double>& w = at.weights();
    for (int g = 0; g < genes_; ++g)
      result.importance[g] = 0.5 * w[g] * w[g] * column2[g] / options_.saliency_probes;
  }

  const Problem& problem_;
  const FitScope& scope_;
  const StiffnessFitOptions& options_;
  const FitContext& context_;
  const int genes_;
  std::vector<ResponseState> states_;  // the current point's and its trials', in turn
  double norm2_ = 0.0;
  std::vector<double> start_;
  double upper_ = 0.0;
  // The regularisation.
  std::vector<double> prior_;
  Vector curvature_;
};

}  // namespace

StiffnessFitResult FitStiffness(const Problem& problem, const std::vector<double>& start,
                                const FitScope& scope, const StiffnessFitOptions& options,
                                const FitContext& context) {
  options.Validate();
  return NamedCaseObjective(problem, start, scope, options, context).Run();
}

}  // namespace springfit
