#include "engine/fit/stiffness_fit.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>

#include "engine/model/equilibrium.h"
#include "engine/problem/force_balance.h"
#include "engine/runtime/options_check.h"

namespace springfit {
namespace {

// Below this normalised error the fit is exact (an MSS reference): nothing is left to fit.
constexpr double kExactError = 1e-24;
// A trust region this small (in the scaled weights' units) has stopped moving the weights.
constexpr double kSmallestRadius = 1e-12;
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

void StiffnessFitOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  check.Require(max_iterations >= 0, "max_iterations", max_iterations, "value >= 0");
  check.Require(InOpenUnit(relative_tolerance), "relative_tolerance", relative_tolerance,
                "0 < value < 1");
  check.Require(max_cg_iterations >= 1, "max_cg_iterations", max_cg_iterations, "value >= 1");
  check.Require(InOpenUnit(cg_tolerance), "cg_tolerance", cg_tolerance, "0 < value < 1");
  check.Require(max_stiffness_ratio > 1.0 && std::isfinite(max_stiffness_ratio),
                "max_stiffness_ratio", max_stiffness_ratio, "1 < value < infinity");
  check.Require(scale_floor > 0.0 && scale_floor <= 1.0, "scale_floor", scale_floor,
                "0 < value <= 1");
  check.Require(saliency_probes >= 0, "saliency_probes", saliency_probes, "value >= 0");
  check.Require(upper_bound >= 0.0 && std::isfinite(upper_bound), "upper_bound", upper_bound,
                "0 <= value < infinity (0: from max_stiffness_ratio)");
  check.Require(max_radius > 0.0 && std::isfinite(max_radius), "max_radius", max_radius,
                "0 < value < infinity");
  check.Require(initial_radius > 0.0 && initial_radius <= max_radius, "initial_radius",
                initial_radius, "0 < value <= max_radius");
  check.Require(regularization >= 0.0 && std::isfinite(regularization), "regularization",
                regularization, "0 <= value < infinity");
}

namespace {

// The projected trust-region Gauss-Newton fit of FitStiffness, as named steps: start, then per
// iteration linearise, a Steihaug step, try it (projected onto the bounds, else stopped short
// of them), accept or reject; then the saliency at the result. Each step that ends the fit
// sets its termination in the result.
class TrustRegionFit {
 public:
  TrustRegionFit(const Problem& problem, const std::vector<double>& start, const FitScope& scope,
                 const StiffnessFitOptions& options, const FitContext& context)
      : problem_(problem),
        scope_(scope),
        options_(options),
        context_(context),
        genes_(problem.gene_count()),
        state_(problem, scope.cases, context),
        norm2_(state_.ReferenceNorm2()) {
    w_ = start;
    w_.resize(static_cast<std::size_t>(genes_), 0.0);
    for (int g = 0; g < genes_; ++g) {
      if (!scope.usable[g] || !(w_[g] > 0.0)) w_[g] = 0.0;
    }
    result_.weights = w_;
    // The upper bound: a spring this much stiffer than the stiffest at the start is rigid for
    // the data (a rigid limit, where the displacements no longer respond to it).
    upper_ = options.upper_bound > 0.0
                 ? options.upper_bound
                 : options.max_stiffness_ratio * *std::max_element(w_.begin(), w_.end());
    scale_.resize(genes_);
    gradient_.resize(genes_);
    free_.resize(static_cast<std::size_t>(genes_));
    trial_.resize(static_cast<std::size_t>(genes_));
  }

  StiffnessFitResult Run() {
    if (!Start()) return result_;
    try {
      while (result_.iterations < options_.max_iterations && Error(data_phi_) > kExactError) {
        if (Interrupted()) throw springfit::Interrupted();
        ++result_.iterations;
        if (!Linearize()) {
          result_.converged = true;
          break;
        }
        if (!Iterate()) break;
      }
    } catch (const springfit::Interrupted&) {
      result_.interrupted = true;  // w and phi are the last accepted step's
    }
    if (Error(data_phi_) <= kExactError) result_.converged = true;
    result_.weights = w_;
    result_.normalized_error = Error(data_phi_);
    result_.solves = state_.solves();
    if (result_.interrupted || options_.saliency_probes == 0) return result_;
    Saliency();
    return result_;
  }

 private:
  double Error(double data_phi) const { return 2.0 * data_phi / norm2_; }
  bool Interrupted() const { return context_.interruption && context_.interruption->Check(); }

  // The start's equilibria (false: it has none, and the fit ends infeasible) and the
  // regularisation: 1/2 mu sum_j ((w_j - p_j) / s_j)^2 over the usable genes (those held at 0
  // add a constant), mu scaled so that its E^2 is `regularization` x the mean square.
  bool Start() {
    if (!state_.Evaluate(w_)) {
      result_.feasible = false;
      result_.normalized_error = result_.initial_normalized_error =
          std::numeric_limits<double>::infinity();
      return false;
    }
    prior_ = scope_.prior.empty() ? w_ : scope_.prior;
    prior_.resize(static_cast<std::size_t>(genes_), 0.0);
    mu_ = options_.regularization * norm2_ / std::max(genes_, 1);
    curvature_ = Vector::Zero(genes_);  // mu / s_j^2 on the usable genes
    if (mu_ > 0.0) {
      const double floor = options_.scale_floor * MedianPositive(prior_);
      for (int g = 0; g < genes_; ++g) {
        if (scope_.usable[g]) curvature_[g] = mu_ / std::pow(std::max(prior_[g], floor), 2);
      }
    }
    // data_phi = 1/2 |r|^2 is what E reports; phi = data_phi + the penalty is what is minimised.
    data_phi_ = 0.5 * state_.residual().squaredNorm();
    phi_ = data_phi_ + Penalty(w_);
    result_.initial_normalized_error = Error(data_phi_);
    radius_ = options_.initial_radius;
    return true;
  }

  double Penalty(const std::vector<double>& x) const {
    double sum = 0.0;
    if (mu_ > 0.0) {
      for (int g = 0; g < genes_; ++g)
        sum += curvature_[g] * (x[g] - prior_[g]) * (x[g] - prior_[g]);
    }
    return 0.5 * sum;
  }

  // out = S J^T J S v on the free genes (plus the regularisation's curvature).
  void ApplyNormal(const Vector& v, Vector& out) {
    Vector sv = v.cwiseProduct(scale_);
    t_ = fb_.a * sv;
    state_.ApplyInverseTangent(t_);  // J S v = H^-1 A S v
    state_.ApplyInverseTangent(t_);  // the adjoint: J^T y = A^T H^-1 y
    out = scale_.cwiseProduct(fb_.a.transpose() * t_);
    if (mu_ > 0.0) out += scale_.cwiseProduct(curvature_).cwiseProduct(sv);
    for (int g = 0; g < genes_; ++g) {
      if (!free_[g]) out[g] = 0.0;
    }
  }

  // The gradient at w by the adjoint, the free genes and their scales; false when the scaled
  // gradient vanishes (a stationary point: converged).
  bool Linearize() {
    fb_ = AssembleForceBalance(problem_, &state_.displacements());
    // The gradient J^T r by the adjoint: one solve per load case.
    t_ = state_.residual();
    state_.ApplyInverseTangent(t_);
    gradient_ = fb_.a.transpose() * t_;
    if (mu_ > 0.0) {
      for (int g = 0; g < genes_; ++g) gradient_[g] += curvature_[g] * (w_[g] - prior_[g]);
    }
    // Weight g moves in units of s_g = max(w_g, scale_floor x the median weight): the trust
    // region bounds each weight's relative change, so a step cannot take a spring to 0 in one
    // stride unless the model asks for it, and an absent spring enters at a typical stiffness.
    const double typical = MedianPositive(w_);
    for (int g = 0; g < genes_; ++g) {
      free_[g] = scope_.usable[g] && !(w_[g] == 0.0 && gradient_[g] >= 0.0) &&
                 !(w_[g] == upper_ && gradient_[g] <= 0.0);
      scale_[g] = free_[g] ? std::max(w_[g], options_.scale_floor * typical) : 0.0;
    }
    gs_ = scale_.cwiseProduct(gradient_);  // zero off the free genes
    gs_norm_ = gs_.norm();
    return gs_norm_ > 0.0;
  }

  // Steihaug's truncated CG on min gs.z + 1/2 z.M z, |z| <= radius: the step z_ and the model's
  // decrease along it. (A Jacobi preconditioner, exact or estimated, was tried: on FEM
  // references it steers the steps into springs the data barely see, which then run to their
  // bounds, and the fit stalls at E 0.05-0.12 where plain CG reaches 0.043 on fem-kidney-2d.)
  double SteihaugStep() {
    z_ = Vector::Zero(genes_);
    cg_r_ = -gs_;
    p_ = cg_r_;
    double rr = cg_r_.squaredNorm();
    for (int it = 0; it < options_.max_cg_iterations; ++it) {
      if (Interrupted()) throw springfit::Interrupted();
      ApplyNormal(p_, mp_);
      const double pmp = p_.dot(mp_);
      // The step to the boundary along p: the largest tau with |z + tau p| = radius.
      const auto to_boundary = [&]() {
        const double a = p_.squaredNorm(), b = 2.0 * z_.dot(p_),
                     c = z_.squaredNorm() - radius_ * radius_;
        return (-b + std::sqrt(std::max(b * b - 4.0 * a * c, 0.0))) / (2.0 * a);
      };
      if (!(pmp > 0.0)) {
        const double tau = to_boundary();
        z_ += tau * p_;
        cg_r_ -= tau * mp_;
        break;
      }
      const double alpha = rr / pmp;
      if ((z_ + alpha * p_).norm() >= radius_) {
        const double tau = to_boundary();
        z_ += tau * p_;
        cg_r_ -= tau * mp_;
        break;
      }
      z_ += alpha * p_;
      cg_r_ -= alpha * mp_;
      const double rr_new = cg_r_.squaredNorm();
      if (std::sqrt(rr_new) <= options_.cg_tolerance * gs_norm_) break;
      p_ = cg_r_ + (rr_new / rr) * p_;
      rr = rr_new;
    }
    // The model's decrease: -(gs.z + 1/2 z.M z), with M z = -gs - cg_r.
    return 0.5 * (cg_r_.dot(z_) - gs_.dot(z_));
  }

  // The model's decrease for the scaled step zs: -(gs.zs + 1/2 zs.M zs) (one more product).
  double ModelDecrease(const Vector& zs) {
    ApplyNormal(zs, mp_);
    return -(gs_.dot(zs) + 0.5 * zs.dot(mp_));
  }

  // Tries w + S zs: its f, and whether it has an equilibrium. The state is then the trial's.
  // Genes in `leaves_` or `caps_` are set exactly to their bound (rounding must not leave a
  // spring at 1e-17 of itself).
  bool Attempt(const Vector& zs) {
    for (int g = 0; g < genes_; ++g) {
      trial_[g] = !free_[g]    ? w_[g]
                  : leaves_[g] ? 0.0
                  : caps_[g]   ? upper_
                               : std::clamp(w_[g] + scale_[g] * zs[g], 0.0, upper_);
    }
    const bool feasible = state_.Evaluate(trial_);
    trial_data_ =
        feasible ? 0.5 * state_.residual().squaredNorm() : std::numeric_limits<double>::infinity();
    trial_phi_ = trial_data_ + Penalty(trial_);
    return feasible;
  }

  // One iteration after the linearisation: a step, tried, accepted or rejected; false ends
  // the fit (converged set where it has).
  bool Iterate() {
    double predicted = SteihaugStep();
    const double step = z_.norm();
    const std::vector<Vector> accepted_u = state_.displacements();
    leaves_.assign(static_cast<std::size_t>(genes_), false);
    caps_.assign(static_cast<std::size_t>(genes_), false);
    // First the step projected onto the bounds (springs whose weight it takes below 0 leave).
    Vector zp = z_;
    bool projected = false;
    for (int g = 0; g < genes_; ++g) {
      if (free_[g] && w_[g] + scale_[g] * z_[g] < 0.0) {
        zp[g] = -w_[g] / scale_[g];
        leaves_[g] = projected = true;
      } else if (free_[g] && w_[g] + scale_[g] * z_[g] > upper_) {
        zp[g] = (upper_ - w_[g]) / scale_[g];
        caps_[g] = projected = true;
      }
    }
    // Should removing those springs fail (near a mechanism the displacements grow like 1 / k,
    // which the Gauss-Newton model cannot see), the same step with each weight it would take
    // out divided by ten instead (its own fraction-to-the-bound: one small spring does not
    // shorten the whole step). Both model decreases are computed here, while the
    // factorisations are the accepted weights'.
    Vector zt;
    double predicted_short = 0.0;
    if (projected) {
      predicted = ModelDecrease(zp);
      zt = z_;
      for (int g = 0; g < genes_; ++g) {
        if (free_[g] && w_[g] + scale_[g] * z_[g] < kShortFraction * w_[g])
          zt[g] = (kShortFraction - 1.0) * w_[g] / scale_[g];
      }
      predicted_short = ModelDecrease(zt);
    }
    bool feasible = Attempt(zp);
    double actual = phi_ - trial_phi_;
    double rho = predicted > 0.0 ? actual / predicted : -1.0;
    if (projected && !(feasible && actual > 0.0 && (rho > 1e-4 || !(predicted > 0.0)))) {
      predicted = predicted_short;
      leaves_.assign(leaves_.size(), false);
      caps_.assign(caps_.size(), false);
      state_.displacements() = accepted_u;
      feasible = Attempt(zt);
      actual = phi_ - trial_phi_;
      rho = predicted > 0.0 ? actual / predicted : -1.0;
    }
    // (A projected step can have a model decrease <= 0 and still lower f: it is taken, and
    // the trust region kept.)
    if (feasible && actual > 0.0 && !(predicted > 0.0)) rho = 0.5;
    if (feasible && actual > 0.0 && rho > 1e-4) return Accept(actual, rho, step);
    return Reject(accepted_u, step);
  }

  // The trial becomes the weights; the trust region grows or shrinks with the model's
  // agreement. False after two decreases in a row below the relative tolerance (converged).
  bool Accept(double actual, double rho, double step) {
    ++result_.accepted;
    small_decreases_ = actual < options_.relative_tolerance * phi_ ? small_decreases_ + 1 : 0;
    w_ = trial_;
    phi_ = trial_phi_;
    data_phi_ = trial_data_;
    if (rho > 0.75 && step >= 0.99 * radius_)
      radius_ = std::min(2.0 * radius_, options_.max_radius);
    if (rho < 0.25) radius_ = 0.25 * step;
    if (context_.on_step) context_.on_step(w_, Error(data_phi_), result_.accepted);
    if (small_decreases_ >= 2) {
      result_.converged = true;
      return false;
    }
    return true;
  }

  // Back to the accepted weights (their equilibria solve at once from where they were), with
  // a smaller trust region. False when it has shrunk to nothing (converged).
  bool Reject(const std::vector<Vector>& accepted_u, double step) {
    state_.displacements() = accepted_u;
    if (!state_.Evaluate(w_)) return false;  // cannot happen: w had an equilibrium
    radius_ = 0.25 * step;
    if (radius_ < kSmallestRadius) {
      result_.converged = true;
      return false;
    }
    return true;
  }

  // Saliency (optimal brain damage, LeCun, Denker and Solla 1990): at an optimum the gradient
  // of a positive weight vanishes, so removing spring j raises f by about 1/2 w_j^2 |J e_j|^2.
  // The column norms are estimated from random-sign products J^T z (E[(J^T z)_j^2] =
  // |J e_j|^2): one solve per load case each, where the exact ones would cost one per gene.
  // The signs come from a fixed seed: deterministic.
  void Saliency() {
    fb_ = AssembleForceBalance(problem_, &state_.displacements());
    Vector column2 = Vector::Zero(genes_);
    t_.resize(state_.residual().size());  // (the loop above may not have run)
    std::mt19937_64 signs(kSaliencySeed);
    for (int probe = 0; probe < options_.saliency_probes; ++probe) {
      for (Eigen::Index row = 0; row < t_.size(); ++row) t_[row] = (signs() >> 63) ? 1.0 : -1.0;
      state_.ApplyInverseTangent(t_);
      column2 += (fb_.a.transpose() * t_).cwiseAbs2();
    }
    result_.solves = state_.solves();
    result_.importance.assign(static_cast<std::size_t>(genes_), 0.0);
    for (int g = 0; g < genes_; ++g)
      result_.importance[g] = 0.5 * w_[g] * w_[g] * column2[g] / options_.saliency_probes;
  }

  const Problem& problem_;
  const FitScope& scope_;
  const StiffnessFitOptions& options_;
  const FitContext& context_;
  const int genes_;
  ResponseState state_;
  const double norm2_;
  StiffnessFitResult result_;
  std::vector<double> w_;
  double upper_ = 0.0;
  // The regularisation.
  std::vector<double> prior_;
  double mu_ = 0.0;
  Vector curvature_;
  double data_phi_ = 0.0;
  double phi_ = 0.0;
  double radius_ = 0.0;
  int small_decreases_ = 0;
  // The linearisation at w.
  ForceBalance fb_;
  Vector scale_, gradient_, gs_;
  double gs_norm_ = 0.0;
  std::vector<bool> free_;
  // The step and its trial.
  Vector z_, cg_r_, p_, mp_, t_;
  std::vector<double> trial_;
  std::vector<bool> leaves_, caps_;
  double trial_phi_ = 0.0;
  double trial_data_ = 0.0;
};

}  // namespace

StiffnessFitResult FitStiffness(const Problem& problem, const std::vector<double>& start,
                                const FitScope& scope, const StiffnessFitOptions& options,
                                const FitContext& context) {
  options.Validate();
  return TrustRegionFit(problem, start, scope, options, context).Run();
}

}  // namespace springfit
