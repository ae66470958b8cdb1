#include "engine/model/equilibrium.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

#include "engine/linalg/newton_iteration.h"
#include "engine/model/rigidity.h"
#include "engine/runtime/number_text.h"
#include "engine/runtime/options_check.h"

namespace springfit {
namespace {

// Shifts tried, in turn, when even the projected Hessian is singular at the current
// configuration (a folded state): a Levenberg-like regularisation of the scaled matrix.
constexpr double kRegularisationShifts[] = {1e-10, 1e-7, 1e-4, 1e-1};
// A unit-stiffness rest factorisation whose smallest scaled pivot is above this has no
// eigenvalue near the mechanism tolerances (RestStabilityOf); healthy models' are 1e-2 and up.
constexpr double kClearPivot = 1e-4;

double MaxAbsOnFree(const Vector& v, const FreeNodes& free, int dim, bool constrained) {
  double m = 0.0;
  for (int node = 0; node < static_cast<int>(free.free_index.size()); ++node) {
    if ((free.free_index[node] < 0) != constrained) continue;
    for (int a = 0; a < dim; ++a) m = std::max(m, std::abs(v[dim * node + a]));
  }
  return m;
}

}  // namespace

void EquilibriumOptions::Validate() const {
  const OptionsCheck check("EquilibriumOptions");
  CheckNewtonSettings(check, *this);
  check.Require(max_step > 0.0 && std::isfinite(max_step), "max_step", max_step,
                "0 < value < infinity");
  check.Require(InOpenUnit(near_mechanism_tolerance), "near_mechanism_tolerance",
                near_mechanism_tolerance, "0 < value < 1");
  check.Require(InOpenUnit(rigidity_tolerance), "rigidity_tolerance", rigidity_tolerance,
                "0 < value < 1");
  check.Require(banded_max_dofs >= 0, "banded_max_dofs", banded_max_dofs, "value >= 0");
  check.Require(supernodal_min_dofs >= 0, "supernodal_min_dofs", supernodal_min_dofs, "value >= 0");
  check.Require(chord_contraction >= 0.0 && chord_contraction < 1.0, "chord_contraction",
                chord_contraction, "0 <= value < 1");
}

EquilibriumSolver::EquilibriumSolver(const SpringGeometry& geometry, FreeNodes free_nodes,
                                     EquilibriumOptions options)
    : geometry_(&geometry),
      free_(std::move(free_nodes)),
      options_(options),
      dim_(geometry.dimension) {
  options_.Validate();
  const int d = dim_;
  const int block = d * d;
  const int n = d * free_.count;
  std::vector<std::pair<int, int>> lower;
  lower.reserve(static_cast<std::size_t>(geometry.size()) * 3 * block);
  for (const NodePair& s : geometry.pairs) {
    const int fi = free_.free_index[s.first];
    const int fj = free_.free_index[s.second];
    if (fi >= 0 && fj >= 0) {
      for (int a = 0; a < d; ++a) {
        for (int b = 0; b < d; ++b) {
          const int r = d * fi + a, c = d * fj + b;
          lower.emplace_back(std::max(r, c), std::min(r, c));
        }
      }
    }
  }
  const auto backend = n <= options_.banded_max_dofs      ? SymmetricSystem::Backend::kBanded
                       : n > options_.supernodal_min_dofs ? SymmetricSystem::Backend::kSupernodal
                                                          : SymmetricSystem::Backend::kSparse;
  // Diagonal blocks of free nodes: the whole lower triangle of each node's d x d block.
  for (int f = 0; f < free_.count; ++f) {
    for (int a = 0; a < d; ++a) {
      for (int b = 0; b < a; ++b) lower.emplace_back(d * f + a, d * f + b);
    }
  }
  system_ = SymmetricSystem(n, std::move(lower), backend);

  slots_.assign(static_cast<std::size_t>(geometry.size()) * 3 * block, -1);
  for (int s = 0; s < geometry.size(); ++s) {
    const int fi = free_.free_index[geometry.pairs[s].first];
    const int fj = free_.free_index[geometry.pairs[s].second];
    int* slot = &slots_[static_cast<std::size_t>(s) * 3 * block];
    for (int a = 0; a < d; ++a) {
      for (int b = 0; b <= a; ++b) {
        if (fi >= 0) slot[a * d + b] = system_.Slot(d * fi + a, d * fi + b);
        if (fj >= 0) slot[block + a * d + b] = system_.Slot(d * fj + a, d * fj + b);
      }
    }
    if (fi >= 0 && fj >= 0) {
      for (int a = 0; a < d; ++a) {
        for (int b = 0; b < d; ++b) {
          const int r = d * fi + a, c = d * fj + b;
          slot[2 * block + a * d + b] = system_.Slot(std::max(r, c), std::min(r, c));
        }
      }
    }
  }
  gradient_.resize(n);
  trial_gradient_.resize(n);
  step_.resize(n);
}

double EquilibriumSolver::Bytes() const {
  const double n = static_cast<double>(system_.size());
  const double nodes = static_cast<double>(free_.free_index.size());
  // (the slots; the gradients, step and trial displacements, all nodes' for the last; each free
  // node's force floor; the rest verdict's unit springs, one per candidate at most)
  return system_.Bytes() + 4.0 * static_cast<double>(slots_.size() + free_.free_index.size()) +
         8.0 * (3.0 * n + nodes * dim_ + static_cast<double>(free_.count)) +
         12.0 * static_cast<double>(geometry_ ? geometry_->size() : 0);
}

template <int D>
double EquilibriumSolver::Assemble(const ActiveSprings& springs, const Vector& force,
                                   const Vector& u, Vector* gradient, bool hessian, bool projected,
                                   double* magnitude) {
  constexpr int kBlock = D * D;
  const SpringGeometry& g = *geometry_;
  const std::vector<int>& fidx = free_.free_index;
  if (gradient) gradient->setZero();
  if (hessian) system_.SetZero();
  double* values = system_.values();
  double energy = 0.0;
  double mag = 0.0;
  for (int a = 0; a < springs.size(); ++a) {
    const int s = springs.index[a];
    const double k = springs.stiffness[a];
    const double l = g.rest_length[s];
    const int i = g.pairs[s].first, j = g.pairs[s].second;
    const VecD<D> d0 = g.rest_separation.template segment<D>(D * s);
    // (d0 + u_i) - u_j, in this order: the examples' loads were scaled with it, bit for bit.
    const SpringState<D> state =
        options_.response == Response::kLinear
            ? SpringState<D>::Linearised(
                  d0, u.template segment<D>(D * i) - u.template segment<D>(D * j), l, k)
            : SpringState<D>(d0 + u.template segment<D>(D * i) - u.template segment<D>(D * j), l,
                             k);
    const double e = state.Energy(l, k);
    energy += e;
    // L - l carries an absolute error of about eps L, so e carries about |k (L - l)| eps L:
    // far more than eps e when the stretch is small.
    mag += e + std::abs(state.tension) * state.length;
    const int fi = fidx[i], fj = fidx[j];
    if (gradient) {
      const VecD<D> pull = state.tension * state.n;
      if (fi >= 0) gradient->template segment<D>(D * fi) += pull;
      if (fj >= 0) gradient->template segment<D>(D * fj) -= pull;
    }
    if (hessian) {
      const MatD<D> K = state.Hessian(l, k, projected);
      const int* slot = &slots_[static_cast<std::size_t>(s) * 3 * kBlock];
      for (int r = 0; r < D; ++r) {
        for (int c = 0; c <= r; ++c) {
          if (fi >= 0) values[slot[r * D + c]] += K(r, c);
          if (fj >= 0) values[slot[kBlock + r * D + c]] += K(r, c);
        }
      }
      if (fi >= 0 && fj >= 0) {
        for (int r = 0; r < D; ++r) {
          for (int c = 0; c < D; ++c) values[slot[2 * kBlock + r * D + c]] -= K(r, c);
        }
      }
    }
  }
  for (int node = 0; node < static_cast<int>(fidx.size()); ++node) {
    const int f = fidx[node];
    if (f < 0) continue;
    const VecD<D> fn = force.template segment<D>(D * node);
    const double work = fn.dot(u.template segment<D>(D * node));
    energy -= work;
    mag += std::abs(work);
    if (gradient) gradient->template segment<D>(D * f) -= fn;
  }
  if (magnitude) *magnitude = mag;
  return energy;
}

double EquilibriumSolver::EnergyAndGradient(const ActiveSprings& springs, const Vector& force,
                                            const Vector& u, Vector* gradient, bool hessian,
                                            bool projected) {
  if (gradient) gradient->resize(dim_ * free_.count);
  if (dim_ == 2) return Assemble<2>(springs, force, u, gradient, hessian, projected, nullptr);
  return Assemble<3>(springs, force, u, gradient, hessian, projected, nullptr);
}

bool EquilibriumSolver::FactorizeTangent(const ActiveSprings& springs, const Vector& u) {
  if (free_.count == 0) return true;
  // The Hessian does not depend on the external forces.
  EnergyAndGradient(springs, Vector::Zero(u.size()), u, nullptr, true, false);
  holds_tangent_ = system_.Factorize(0.0, options_.pivot_tolerance, false).positive_definite;
  return holds_tangent_;
}

bool EquilibriumSolver::SolveWithTangent(const ActiveSprings& springs, const Vector& /*force*/,
                                         const Vector& u, Matrix& rhs) {
  if (free_.count == 0) return true;
  if (!FactorizeTangent(springs, u)) return false;
  Vector column(rhs.rows());
  for (Eigen::Index c = 0; c < rhs.cols(); ++c) {
    column = rhs.col(c);
    system_.Solve(column);
    rhs.col(c) = column;
  }
  return true;
}

EquilibriumSolver::Resolution EquilibriumSolver::DisplacementResolution(
    const ActiveSprings& springs, const Vector& u) {
  Resolution resolution;
  if (free_.count == 0) return resolution;
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  const Vector zero = Vector::Zero(u.size());
  holds_tangent_ = false;
  // The exact tangent, with any positive pivot: a step would not trust one this small, but
  // the size of H^-1 r is what is asked, and the softest direction decides it.
  EnergyAndGradient(springs, zero, u, nullptr, true, false);
  if (!system_.Factorize(0.0, 0.0, false).positive_definite) {
    // A saddle: round-off still moves it by H^-1 r (the projected tangent would drop the very
    // directions that make it unstable, or be singular along them). A negative pivot of the
    // LDLT says a saddle (Sylvester's law of inertia); a zero one, a singular tangent, which
    // says neither.
    const SymmetricSystem::Factorization f = system_.FactorizeIndefinite(0.0);
    if (f.min_pivot == 0.0) {
      resolution.spread = kInfinity;
      return resolution;
    }
    resolution.stable = f.min_pivot > 0.0;
  }
  // Each free node's allowed imbalance, with signs that do not line up with any one mode.
  Vector r(dim_ * free_.count);
  for (int f = 0; f < free_.count; ++f) {
    const double tol = std::max(relative_, f < static_cast<int>(floor_.size()) ? floor_[f] : 0.0);
    for (int a = 0; a < dim_; ++a) {
      const std::uint32_t hash = static_cast<std::uint32_t>(dim_ * f + a) * 2654435761u;
      r[dim_ * f + a] = (hash >> 31) ? tol : -tol;
    }
  }
  system_.Solve(r);
  resolution.spread = std::isfinite(r.norm()) ? r.norm() : kInfinity;
  return resolution;
}

Matrix EquilibriumSolver::AssembledHessian() const {
  return system_.ToDense();
}

void EquilibriumSolver::AssembleUnitRest(const ActiveSprings& springs) {
  unit_.index = springs.index;
  unit_.stiffness.assign(springs.index.size(), 1.0);
  const Vector zero = Vector::Zero(static_cast<Eigen::Index>(free_.free_index.size()) * dim_);
  // At rest L = l, so the exact Hessian is the linear stiffness sum k n n^T.
  EnergyAndGradient(unit_, zero, zero, nullptr, true, false);
}

RestStability EquilibriumSolver::RestStabilityOf(const ActiveSprings& springs) {
  RestStability r;
  if (free_.count == 0) return r;
  holds_tangent_ = false;
  AssembleUnitRest(springs);
  const SymmetricSystem::Factorization f =
      system_.Factorize(0.0, options_.near_mechanism_tolerance, true);
  // A Cholesky that succeeds with every pivot above the tolerance proves nothing about the
  // smallest eigenvalue, which can be far below the smallest pivot (a thin strip of cells):
  // unless every pivot is well clear of it, the eigenvalues are counted.
  const int small = f.positive_definite && f.min_pivot < kClearPivot
                        ? system_.CountEigenvaluesBelow(0.0, options_.near_mechanism_tolerance)
                        : f.small_pivots;
  if (small == 0) return r;
  r.modes = std::min(small, RigidityRankDeficiency(*geometry_, free_, springs,
                                                   options_.rigidity_tolerance, small));
  r.near_modes = small - r.modes;
  return r;
}

EquilibriumSummary EquilibriumSolver::Solve(const ActiveSprings& springs, const Vector& force,
                                            const Vector& prescribed, Vector& u) {
  return Solve(springs, force, prescribed, u, nullptr);
}

EquilibriumSummary EquilibriumSolver::Solve(const ActiveSprings& springs, const Vector& force,
                                            const Vector& prescribed, Vector& u,
                                            const EquilibriumSolver* start_tangent) {
  return dim_ == 2 ? SolveImpl<2>(springs, force, prescribed, u, start_tangent)
                   : SolveImpl<3>(springs, force, prescribed, u, start_tangent);
}

template <int D>
double EquilibriumSolver::ForceScale(const ActiveSprings& springs, const Vector& force,
                                     const Vector& prescribed) const {
  // The external forces, and the force each spring to a node with a prescribed displacement
  // exerts when its free end has not moved (its own stiffness, not the stiffest spring's: a
  // node displaced on soft springs is loaded softly).
  double scale = MaxAbsOnFree(force, free_, D, false);
  for (int a = 0; a < springs.size(); ++a) {
    const int s = springs.index[a];
    for (const int node : {geometry_->pairs[s].first, geometry_->pairs[s].second}) {
      if (free_.free_index[node] < 0)
        scale =
            std::max(scale, springs.stiffness[a] * prescribed.template segment<D>(D * node).norm());
    }
  }
  return scale;
}

double EquilibriumSolver::SetRoundoffFloors(const ActiveSprings& springs) {
  // Each spring's force carries about eps k l (L - l is computed to about eps l), so a node's
  // floor is the largest k l among its springs, times roundoff_force_tolerance (eps times a few
  // hundred: the springs at a node add their errors). Per node, so that the scene's stiffest
  // spring does not hide a soft region.
  floor_.assign(free_.count, 0.0);
  for (int a = 0; a < springs.size(); ++a) {
    const int s = springs.index[a];
    const double kl = springs.stiffness[a] * geometry_->rest_length[s];
    for (const int node : {geometry_->pairs[s].first, geometry_->pairs[s].second}) {
      const int f = free_.free_index[node];
      if (f >= 0) floor_[f] = std::max(floor_[f], options_.roundoff_force_tolerance * kl);
    }
  }
  double floor_max = 0.0;
  for (const double f : floor_) floor_max = std::max(floor_max, f);
  return floor_max;
}

template <int D>
double EquilibriumSolver::Excess(const Vector& gradient) const {
  double worst = 0.0;
  for (int f = 0; f < free_.count; ++f) {
    const double tol = std::max(relative_, floor_[f]);
    worst = std::max(worst,
                     gradient.template segment<D>(D * f).template lpNorm<Eigen::Infinity>() / tol);
  }
  return worst;
}

const char* EquilibriumSolver::StopBeforeStep(EquilibriumSummary& summary) {
  if (summary.excess <= 1.0) {
    summary.termination = Termination::kConverged;
    return "";
  }
  if (summary.iterations >= options_.max_iterations)
    return "the Newton iteration limit was reached";
  if (interruption_ && interruption_->Check()) {
    summary.termination = Termination::kInterrupted;
    return "";
  }
  return nullptr;
}

template <int D>
const char* EquilibriumSolver::NewtonStep(const ActiveSprings& springs, const Vector& force,
                                          const Vector& u, EquilibriumSummary& summary,
                                          double& slope) {
  chord_step_ = chord_ != nullptr && options_.chord_contraction > 0.0 &&
                contraction_ <= options_.chord_contraction;
  if (chord_step_) {
    ++summary.chord_steps;
    step_ = -gradient_;
    chord_->system_.Solve(step_);
    return LimitStep<D>(springs, slope);
  }
  // The exact Hessian when positive definite, else the projected one, else the projected one
  // regularised.
  holds_tangent_ = false;
  chord_ = nullptr;
  SymmetricSystem::Factorization f = system_.Factorize(0.0, options_.pivot_tolerance, false);
  if (!f.positive_definite) {
    ++summary.projected_steps;
    Assemble<D>(springs, force, u, nullptr, true, true, nullptr);
    f = system_.Factorize(0.0, options_.pivot_tolerance, false);
    for (double shift : kRegularisationShifts) {
      if (f.positive_definite) break;
      f = system_.Factorize(shift, options_.pivot_tolerance, false);
    }
    if (!f.positive_definite) return "the Hessian stayed singular after regularisation";
  }
  holds_tangent_ = true;
  chord_ = this;
  step_ = -gradient_;
  system_.Solve(step_);
  return LimitStep<D>(springs, slope);
}

template <int D>
const char* EquilibriumSolver::LimitStep(const ActiveSprings& springs, double& slope) {
  // A step that changes some spring's separation by more than a fraction of its length leaves
  // the region where the quadratic model means anything: it can jump a node onto another
  // (L = 0, where E has a cone) or across a fixed node. Shorten it; the line search does the
  // rest. Large but smooth displacements (a long grid under stretch) are not limited.
  double largest = 0.0;
  for (int a = 0; a < springs.size(); ++a) {
    const int s = springs.index[a];
    const int fi = free_.free_index[geometry_->pairs[s].first];
    const int fj = free_.free_index[geometry_->pairs[s].second];
    VecD<D> change = VecD<D>::Zero();
    if (fi >= 0) change += step_.template segment<D>(D * fi);
    if (fj >= 0) change -= step_.template segment<D>(D * fj);
    largest = std::max(largest, change.norm() / geometry_->rest_length[s]);
  }
  // (The linearised model has no cone: its Newton step is the answer, whatever its size.)
  if (largest > options_.max_step && options_.response == Response::kNonlinear)
    step_ *= options_.max_step / largest;
  slope = gradient_.dot(step_);
  if (!(slope < 0.0))  // not a descent direction (also catches NaN)
    return "the Newton step is not a descent direction (round-off in the Hessian)";
  return nullptr;
}

template <int D>
EnergyPoint EquilibriumSolver::TrialPoint(const ActiveSprings& springs, const Vector& force,
                                          const Vector& u, double alpha) {
  // Each trial also assembles the gradient and the exact Hessian: the full step is accepted
  // almost always, and then the next iteration needs them.
  const int nodes = static_cast<int>(free_.free_index.size());
  trial_u_ = u;
  for (int node = 0; node < nodes; ++node) {
    const int fi = free_.free_index[node];
    if (fi >= 0)
      trial_u_.template segment<D>(D * node) += alpha * step_.template segment<D>(D * fi);
  }
  EnergyPoint trial;
  trial.energy =
      Assemble<D>(springs, force, trial_u_, &trial_gradient_, true, false, &trial.magnitude);
  trial.residual = trial_gradient_.template lpNorm<Eigen::Infinity>();
  return trial;
}

// Newton's steps (newton_iteration.h) on the solver's state.
template <int D>
struct EquilibriumSolver::NewtonSteps {
  EquilibriumSolver& solver;
  const ActiveSprings& springs;
  const Vector& force;
  Vector& u;
  EquilibriumSummary& summary;

  // (The iteration count is summary.iterations, which NewtonIterate counts; the excess is
  // per node, from the gradient, not from |gradient|_inf alone.)
  double residual_before = 0.0;  // the largest imbalance before the step (chord steps)

  const char* StopBeforeStep(int, const EnergyPoint& at) {
    summary.excess = solver.Excess<D>(solver.gradient_);
    residual_before = at.residual;
    return solver.StopBeforeStep(summary);
  }
  const char* Direction(double& slope) {
    return solver.NewtonStep<D>(springs, force, u, summary, slope);
  }
  EnergyPoint Trial(double alpha) { return solver.TrialPoint<D>(springs, force, u, alpha); }
  // The trial's gradient and Hessian are the new point's.
  const char* Accept(EnergyPoint& at) {
    u.swap(solver.trial_u_);
    solver.gradient_.swap(solver.trial_gradient_);
    solver.contraction_ = residual_before > 0.0 ? at.residual / residual_before : 0.0;
    return nullptr;
  }
  // Restores the Hessian of the current point for a caller that inspects it.
  void Reject() { solver.Assemble<D>(springs, force, u, &solver.gradient_, true, false, nullptr); }
};

template <int D>
EquilibriumSummary EquilibriumSolver::SolveImpl(const ActiveSprings& springs, const Vector& force,
                                                const Vector& prescribed, Vector& u,
                                                const EquilibriumSolver* start_tangent) {
  EquilibriumSummary summary;
  const int nodes = static_cast<int>(free_.free_index.size());
  for (int node = 0; node < nodes; ++node) {
    if (free_.free_index[node] < 0)
      u.template segment<D>(D * node) = prescribed.template segment<D>(D * node);
  }
  if (free_.count == 0) {
    summary.termination = Termination::kConverged;
    return summary;
  }
  // Converged when every free node's imbalance is within its tolerance: the relative one
  // (of the load's force scale), or its round-off floor if larger.
  double force_scale = ForceScale<D>(springs, force, prescribed);
  const double floor_max = SetRoundoffFloors(springs);
  if (force_scale == 0.0) force_scale = floor_max / options_.roundoff_force_tolerance;
  relative_ = options_.relative_force_tolerance * force_scale;

  EnergyPoint at;
  at.energy = Assemble<D>(springs, force, u, &gradient_, true, false, &at.magnitude);
  at.residual = gradient_.template lpNorm<Eigen::Infinity>();
  summary.initial_residual = at.residual / force_scale;
  // The loosest node's tolerance: a property of the scene and the load, whatever the unit.
  summary.tolerance = std::max(relative_, floor_max) / force_scale;
  trial_u_.resize(u.size());

  NewtonSteps<D> steps{*this, springs, force, u, summary};
  const LineSearchOptions search{options_.armijo, options_.max_line_search_steps + 1,
                                 RoundoffRule::kGradientDecides};
  chord_ = start_tangent != nullptr && start_tangent->holds_tangent_ ? start_tangent : nullptr;
  contraction_ = 0.0;
  chord_step_ = false;
  for (;;) {
    summary.why = NewtonIterate(steps, at, search, summary.iterations, &summary.line_search_steps);
    // A chord step the line search refused is retried with the tangent at the point.
    if (summary.converged() || summary.termination == Termination::kInterrupted || !chord_step_)
      break;
    contraction_ = std::numeric_limits<double>::infinity();
    chord_step_ = false;
  }
  chord_ = nullptr;
  summary.final_residual = at.residual / force_scale;
  if (!summary.converged()) summary.excess = Excess<D>(gradient_);
  return summary;
}

std::string NotConvergedText(const EquilibriumSummary& summary) {
  return std::string(summary.why) + " after " + std::to_string(summary.iterations) +
         " iterations, with a force imbalance " + NumberText(summary.excess) +
         " times what its node allows (relative force residual " +
         NumberText(summary.final_residual) + ")";
}

std::string PrecisionLimitText(const RestStability& stability, const ActiveSprings& springs) {
  std::string text;
  if (stability.near_modes > 0) {
    text += "; the model is rigid but along " + std::to_string(stability.near_modes) +
            " directions its stiffness is below " +
            NumberText(EquilibriumOptions{}.near_mechanism_tolerance) +
            " of its stiffest (nearly collinear springs, or a very thin layer of cells): "
            "double precision cannot resolve its equilibrium there";
  }
  double k_min = 0.0, k_max = 0.0;
  for (std::size_t a = 0; a < springs.stiffness.size(); ++a) {
    const double k = springs.stiffness[a];
    k_min = a == 0 ? k : std::min(k_min, k);
    k_max = std::max(k_max, k);
  }
  if (k_min > 0.0 && k_max / k_min >= kStiffnessRatioLimit) {
    text += "; its spring stiffness spans a ratio of " + NumberText(k_max / k_min) +
            ", at or beyond what double precision resolves (about " +
            NumberText(kStiffnessRatioLimit, 1) + ")";
  }
  return text;
}

template double EquilibriumSolver::Assemble<2>(const ActiveSprings&, const Vector&, const Vector&,
                                               Vector*, bool, bool, double*);
template double EquilibriumSolver::Assemble<3>(const ActiveSprings&, const Vector&, const Vector&,
                                               Vector*, bool, bool, double*);

}  // namespace springfit
