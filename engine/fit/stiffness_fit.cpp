#include "engine/fit/stiffness_fit.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>

#include "engine/options_check.h"
#include "engine/problem/force_balance.h"

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

double MedianPositive(const std::vector<double>& w) {
  std::vector<double> positive;
  for (double x : w) {
    if (x > 0.0) positive.push_back(x);
  }
  if (positive.empty()) return 1.0;
  const auto mid = positive.begin() + static_cast<std::ptrdiff_t>(positive.size() / 2);
  std::nth_element(positive.begin(), mid, positive.end());
  return *mid;
}

int PresentSprings(const std::vector<double>& weights) {
  return static_cast<int>(
      std::count_if(weights.begin(), weights.end(), [](double w) { return w > 0.0; }));
}

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

StiffnessFitResult FitStiffness(const Problem& problem, const std::vector<double>& start,
                                const FitScope& scope, const StiffnessFitOptions& options,
                                const FitContext& context) {
  Interruption* interruption = context.interruption;
  options.Validate();
  const int genes = problem.gene_count();
  const std::vector<bool>& usable = scope.usable;
  StiffnessFitResult result;
  std::vector<double> w(start);
  w.resize(static_cast<std::size_t>(genes), 0.0);
  for (int g = 0; g < genes; ++g) {
    if (!usable[g] || !(w[g] > 0.0)) w[g] = 0.0;
  }
  result.weights = w;

  // The upper bound: a spring this much stiffer than the stiffest at the start is rigid for
  // the data (a rigid limit, where the displacements no longer respond to it).
  const double upper = options.upper_bound > 0.0
                           ? options.upper_bound
                           : options.max_stiffness_ratio * *std::max_element(w.begin(), w.end());
  ResponseState state(problem, scope.cases, context);
  const double norm2 = state.ReferenceNorm2();
  if (!state.Evaluate(w)) {
    result.feasible = false;
    result.normalized_error = result.initial_normalized_error =
        std::numeric_limits<double>::infinity();
    return result;
  }
  // The regularisation: 1/2 mu sum_j ((w_j - p_j) / s_j)^2 over the usable genes (those held
  // at 0 add a constant), mu scaled so that its E^2 is `regularization` x the mean square.
  std::vector<double> prior = scope.prior.empty() ? w : scope.prior;
  prior.resize(static_cast<std::size_t>(genes), 0.0);
  const double mu = options.regularization * norm2 / std::max(genes, 1);
  Vector curvature = Vector::Zero(genes);  // mu / s_j^2 on the usable genes
  if (mu > 0.0) {
    const double floor = options.scale_floor * MedianPositive(prior);
    for (int g = 0; g < genes; ++g) {
      if (usable[g]) curvature[g] = mu / std::pow(std::max(prior[g], floor), 2);
    }
  }
  const auto penalty = [&](const std::vector<double>& x) {
    double sum = 0.0;
    if (mu > 0.0) {
      for (int g = 0; g < genes; ++g) sum += curvature[g] * (x[g] - prior[g]) * (x[g] - prior[g]);
    }
    return 0.5 * sum;
  };
  // data_phi = 1/2 |r|^2 is what E reports; phi = data_phi + the penalty is what is minimised.
  double data_phi = 0.5 * state.residual().squaredNorm();
  double phi = data_phi + penalty(w);
  result.initial_normalized_error = 2.0 * data_phi / norm2;

  double radius = options.initial_radius;
  int small_decreases = 0;
  ForceBalance fb;
  Vector scale(genes), gradient(genes), z, cg_r, p, mp, t;
  std::vector<bool> free(static_cast<std::size_t>(genes));
  std::vector<double> trial(static_cast<std::size_t>(genes));
  const auto apply_normal = [&](const Vector& v, Vector& out) {
    // out = S J^T J S v on the free genes.
    Vector sv = v.cwiseProduct(scale);
    t = fb.a * sv;
    state.ApplyInverseTangent(t);  // J S v = H^-1 A S v
    state.ApplyInverseTangent(t);  // the adjoint: J^T y = A^T H^-1 y
    out = scale.cwiseProduct(fb.a.transpose() * t);
    if (mu > 0.0) out += scale.cwiseProduct(curvature).cwiseProduct(sv);
    for (int g = 0; g < genes; ++g) {
      if (!free[g]) out[g] = 0.0;
    }
  };

  try {
    while (result.iterations < options.max_iterations && 2.0 * data_phi / norm2 > kExactError) {
      if (interruption && interruption->Check()) throw Interrupted();
      ++result.iterations;
      fb = AssembleForceBalance(problem, &state.displacements());
      // The gradient J^T r by the adjoint: one solve per load case.
      t = state.residual();
      state.ApplyInverseTangent(t);
      gradient = fb.a.transpose() * t;
      if (mu > 0.0) {
        for (int g = 0; g < genes; ++g) gradient[g] += curvature[g] * (w[g] - prior[g]);
      }
      // Weight g moves in units of s_g = max(w_g, scale_floor x the median weight): the trust
      // region bounds each weight's relative change, so a step cannot take a spring to 0 in one
      // stride unless the model asks for it, and an absent spring enters at a typical stiffness.
      const double typical = MedianPositive(w);
      for (int g = 0; g < genes; ++g) {
        free[g] = usable[g] && !(w[g] == 0.0 && gradient[g] >= 0.0) &&
                  !(w[g] == upper && gradient[g] <= 0.0);
        scale[g] = free[g] ? std::max(w[g], options.scale_floor * typical) : 0.0;
      }
      const Vector gs = scale.cwiseProduct(gradient);  // zero off the free genes
      const double gs_norm = gs.norm();
      if (!(gs_norm > 0.0)) {
        result.converged = true;
        break;
      }
      // Steihaug's truncated CG on min gs.z + 1/2 z.M z, |z| <= radius. (A Jacobi preconditioner,
      // exact or estimated, was tried: on FEM references it steers the steps into springs the
      // data barely see, which then run to their bounds, and the fit stalls at E 0.05-0.12
      // where plain CG reaches 0.043 on fem-kidney-2d.)
      z = Vector::Zero(genes);
      cg_r = -gs;
      p = cg_r;
      double rr = cg_r.squaredNorm();
      for (int it = 0; it < options.max_cg_iterations; ++it) {
        if (interruption && interruption->Check()) throw Interrupted();
        apply_normal(p, mp);
        const double pmp = p.dot(mp);
        // The step to the boundary along p: the largest tau with |z + tau p| = radius.
        const auto to_boundary = [&]() {
          const double a = p.squaredNorm(), b = 2.0 * z.dot(p),
                       c = z.squaredNorm() - radius * radius;
          return (-b + std::sqrt(std::max(b * b - 4.0 * a * c, 0.0))) / (2.0 * a);
        };
        if (!(pmp > 0.0)) {
          const double tau = to_boundary();
          z += tau * p;
          cg_r -= tau * mp;
          break;
        }
        const double alpha = rr / pmp;
        if ((z + alpha * p).norm() >= radius) {
          const double tau = to_boundary();
          z += tau * p;
          cg_r -= tau * mp;
          break;
        }
        z += alpha * p;
        cg_r -= alpha * mp;
        const double rr_new = cg_r.squaredNorm();
        if (std::sqrt(rr_new) <= options.cg_tolerance * gs_norm) break;
        p = cg_r + (rr_new / rr) * p;
        rr = rr_new;
      }
      // The model's decrease: -(gs.z + 1/2 z.M z), with M z = -gs - cg_r.
      double predicted = 0.5 * (cg_r.dot(z) - gs.dot(z));
      const double step = z.norm();

      // The model's decrease for the scaled step zs: -(gs.zs + 1/2 zs.M zs) (one more product).
      const auto model_decrease = [&](const Vector& zs) {
        apply_normal(zs, mp);
        return -(gs.dot(zs) + 0.5 * zs.dot(mp));
      };
      const std::vector<Vector> accepted_u = state.displacements();
      // Tries w + S zs: its f, and whether it has an equilibrium. The state is then the trial's.
      double trial_phi = std::numeric_limits<double>::infinity(), trial_data = trial_phi;
      // Set exactly to a bound (rounding must not leave a spring at 1e-17 of itself).
      std::vector<bool> leaves(static_cast<std::size_t>(genes), false);
      std::vector<bool> caps(static_cast<std::size_t>(genes), false);
      const auto attempt = [&](const Vector& zs) {
        for (int g = 0; g < genes; ++g) {
          trial[g] = !free[g]    ? w[g]
                     : leaves[g] ? 0.0
                     : caps[g]   ? upper
                                 : std::clamp(w[g] + scale[g] * zs[g], 0.0, upper);
        }
        const bool feasible = state.Evaluate(trial);
        trial_data = feasible ? 0.5 * state.residual().squaredNorm()
                              : std::numeric_limits<double>::infinity();
        trial_phi = trial_data + penalty(trial);
        return feasible;
      };
      // First the step projected onto the bounds (springs whose weight it takes below 0 leave).
      Vector zp = z;
      bool projected = false;
      for (int g = 0; g < genes; ++g) {
        if (free[g] && w[g] + scale[g] * z[g] < 0.0) {
          zp[g] = -w[g] / scale[g];
          leaves[g] = projected = true;
        } else if (free[g] && w[g] + scale[g] * z[g] > upper) {
          zp[g] = (upper - w[g]) / scale[g];
          caps[g] = projected = true;
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
        predicted = model_decrease(zp);
        zt = z;
        for (int g = 0; g < genes; ++g) {
          if (free[g] && w[g] + scale[g] * z[g] < kShortFraction * w[g])
            zt[g] = (kShortFraction - 1.0) * w[g] / scale[g];
        }
        predicted_short = model_decrease(zt);
      }
      bool feasible = attempt(zp);
      double actual = phi - trial_phi;
      double rho = predicted > 0.0 ? actual / predicted : -1.0;
      if (projected && !(feasible && actual > 0.0 && (rho > 1e-4 || !(predicted > 0.0)))) {
        predicted = predicted_short;
        leaves.assign(leaves.size(), false);
        caps.assign(caps.size(), false);
        state.displacements() = accepted_u;
        feasible = attempt(zt);
        actual = phi - trial_phi;
        rho = predicted > 0.0 ? actual / predicted : -1.0;
      }
      // (A projected step can have a model decrease <= 0 and still lower f: it is taken, and
      // the trust region kept.)
      if (feasible && actual > 0.0 && !(predicted > 0.0)) rho = 0.5;
      if (feasible && actual > 0.0 && rho > 1e-4) {
        ++result.accepted;
        small_decreases = actual < options.relative_tolerance * phi ? small_decreases + 1 : 0;
        w = trial;
        phi = trial_phi;
        data_phi = trial_data;
        if (rho > 0.75 && step >= 0.99 * radius)
          radius = std::min(2.0 * radius, options.max_radius);
        if (rho < 0.25) radius = 0.25 * step;
        if (context.on_step) context.on_step(w, 2.0 * data_phi / norm2, result.accepted);
        if (small_decreases >= 2) {
          result.converged = true;
          break;
        }
      } else {
        // Back to the accepted weights (their equilibria solve at once from where they were).
        state.displacements() = accepted_u;
        if (!state.Evaluate(w)) break;  // cannot happen: w had an equilibrium
        radius = 0.25 * step;
        if (radius < kSmallestRadius) {
          result.converged = true;
          break;
        }
      }
    }
  } catch (const Interrupted&) {
    result.interrupted = true;  // w and phi are the last accepted step's
  }
  if (2.0 * data_phi / norm2 <= kExactError) result.converged = true;

  result.weights = w;
  result.normalized_error = 2.0 * data_phi / norm2;
  result.solves = state.solves();
  if (result.interrupted || options.saliency_probes == 0) return result;
  // Saliency (optimal brain damage, LeCun, Denker and Solla 1990): at an optimum the gradient
  // of a positive weight vanishes, so removing spring j raises f by about 1/2 w_j^2 |J e_j|^2.
  // The column norms are estimated from random-sign products J^T z (E[(J^T z)_j^2] =
  // |J e_j|^2): one solve per load case each, where the exact ones would cost one per gene.
  // The signs come from a fixed seed: deterministic.
  fb = AssembleForceBalance(problem, &state.displacements());
  Vector column2 = Vector::Zero(genes);
  t.resize(state.residual().size());  // (the loop above may not have run)
  std::mt19937_64 signs(kSaliencySeed);
  for (int probe = 0; probe < options.saliency_probes; ++probe) {
    for (Eigen::Index row = 0; row < t.size(); ++row) t[row] = (signs() >> 63) ? 1.0 : -1.0;
    state.ApplyInverseTangent(t);
    column2 += (fb.a.transpose() * t).cwiseAbs2();
  }
  result.solves = state.solves();
  result.importance.assign(static_cast<std::size_t>(genes), 0.0);
  for (int g = 0; g < genes; ++g)
    result.importance[g] = 0.5 * w[g] * w[g] * column2[g] / options.saliency_probes;
  return result;
}

}  // namespace springfit
