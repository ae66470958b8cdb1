#include "engine/equilibrium.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

#include "engine/options_check.h"

namespace springfit {
namespace {

constexpr double kEpsilon = std::numeric_limits<double>::epsilon();
// An energy comparison is decided only beyond this many ulps of the energy's magnitude (the
// scale of its rounding error, see Assemble): near the solution the true decrease falls below
// the rounding of E (DESIGN.md).
constexpr double kEnergyRoundoffUlps = 64.0;
// Shifts tried, in turn, when even the projected Hessian is singular at the current
// configuration (a folded state): a Levenberg-like regularisation of the scaled matrix.
constexpr double kRegularisationShifts[] = {1e-10, 1e-7, 1e-4, 1e-1};

double MaxAbsOnFree(const Vector& v, const FreeNodes& free, int dim, bool constrained) {
  double m = 0.0;
  for (int node = 0; node < static_cast<int>(free.free_index.size()); ++node) {
    if ((free.free_index[node] < 0) != constrained) continue;
    for (int a = 0; a < dim; ++a) m = std::max(m, std::abs(v[dim * node + a]));
  }
  return m;
}

}  // namespace

FreeNodes FreeNodes::FromConstrained(const std::vector<bool>& constrained) {
  FreeNodes f;
  f.free_index.assign(constrained.size(), -1);
  for (std::size_t node = 0; node < constrained.size(); ++node) {
    if (!constrained[node]) f.free_index[node] = f.count++;
  }
  return f;
}

void EquilibriumOptions::Validate() const {
  const OptionsCheck check("EquilibriumOptions");
  CheckNewtonSettings(check, *this);
  check.Require(max_step > 0.0 && std::isfinite(max_step), "max_step", max_step,
                "0 < value < infinity");
  check.Require(mechanism_shift > 0.0 && mechanism_shift < pivot_tolerance, "mechanism_shift",
                mechanism_shift, "0 < value < pivot_tolerance");
  check.Require(banded_max_dofs >= 0, "banded_max_dofs", banded_max_dofs, "value >= 0");
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
  const auto backend = n <= options_.banded_max_dofs ? SymmetricSystem::Backend::kBanded
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
  return system_.Factorize(0.0, options_.pivot_tolerance, false).positive_definite;
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

Matrix EquilibriumSolver::AssembledHessian() const {
  return system_.ToDense();
}

int EquilibriumSolver::RestMechanismModes(const ActiveSprings& springs) {
  if (free_.count == 0) return 0;
  const Vector zero_u = Vector::Zero(static_cast<Eigen::Index>(free_.free_index.size()) * dim_);
  const Vector zero_f = zero_u;
  // At rest L = l, so the exact Hessian is the linear stiffness sum k n n^T.
  EnergyAndGradient(springs, zero_f, zero_u, nullptr, true, false);
  const SymmetricSystem::Factorization f =
      system_.Factorize(options_.mechanism_shift, options_.pivot_tolerance, true);
  return f.small_pivots;
}

EquilibriumSummary EquilibriumSolver::Solve(const ActiveSprings& springs, const Vector& force,
                                            const Vector& prescribed, Vector& u) {
  return dim_ == 2 ? SolveImpl<2>(springs, force, prescribed, u)
                   : SolveImpl<3>(springs, force, prescribed, u);
}

template <int D>
EquilibriumSummary EquilibriumSolver::SolveImpl(const ActiveSprings& springs, const Vector& force,
                                                const Vector& prescribed, Vector& u) {
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
  const double k_max = springs.MaxStiffness();
  const double l_max = geometry_->MaxRestLength();
  double force_scale = std::max(MaxAbsOnFree(force, free_, D, false),
                                k_max * MaxAbsOnFree(prescribed, free_, D, true));
  if (force_scale == 0.0) force_scale = k_max * l_max;  // nothing loads: judge against k l
  const double tolerance = std::max(options_.relative_force_tolerance * force_scale,
                                    options_.roundoff_force_tolerance * k_max * l_max);

  double magnitude = 0.0;
  double energy = Assemble<D>(springs, force, u, &gradient_, true, false, &magnitude);
  double residual = gradient_.template lpNorm<Eigen::Infinity>();
  summary.initial_residual = residual / force_scale;
  trial_u_.resize(u.size());

  for (;;) {
    if (residual <= tolerance) {
      summary.termination = Termination::kConverged;
      break;
    }
    if (summary.iterations >= options_.max_iterations) break;
    if (interruption_ && interruption_->Check()) {
      summary.termination = Termination::kInterrupted;
      break;
    }

    // Newton direction: exact Hessian when positive definite, else the projected one, else
    // the projected one regularised.
    SymmetricSystem::Factorization f = system_.Factorize(0.0, options_.pivot_tolerance, false);
    if (!f.positive_definite) {
      ++summary.projected_steps;
      Assemble<D>(springs, force, u, nullptr, true, true, nullptr);
      f = system_.Factorize(0.0, options_.pivot_tolerance, false);
      for (double shift : kRegularisationShifts) {
        if (f.positive_definite) break;
        f = system_.Factorize(shift, options_.pivot_tolerance, false);
      }
      if (!f.positive_definite) break;
    }
    step_ = -gradient_;
    system_.Solve(step_);
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
    const double slope = gradient_.dot(step_);
    if (!(slope < 0.0)) break;  // not a descent direction (also catches NaN)

    // Backtracking line search on E. Each trial also assembles the gradient and the exact
    // Hessian: the full step is accepted almost always, and then the next iteration needs them.
    double alpha = 1.0;
    bool accepted = false;
    for (int ls = 0; ls <= options_.max_line_search_steps; ++ls) {
      trial_u_ = u;
      for (int node = 0; node < nodes; ++node) {
        const int fi = free_.free_index[node];
        if (fi >= 0)
          trial_u_.template segment<D>(D * node) += alpha * step_.template segment<D>(D * fi);
      }
      double trial_magnitude = 0.0;
      const double trial_energy =
          Assemble<D>(springs, force, trial_u_, &trial_gradient_, true, false, &trial_magnitude);
      const double roundoff = kEnergyRoundoffUlps * kEpsilon * std::max(magnitude, trial_magnitude);
      const double trial_residual = trial_gradient_.template lpNorm<Eigen::Infinity>();
      const bool sufficient_decrease = trial_energy <= energy + options_.armijo * alpha * slope;
      // Within round-off of E, the gradient is the better judge of progress.
      const bool roundoff_progress =
          std::abs(trial_energy - energy) <= roundoff && trial_residual < residual;
      if (std::isfinite(trial_energy) && (sufficient_decrease || roundoff_progress)) {
        u.swap(trial_u_);
        gradient_.swap(trial_gradient_);
        energy = trial_energy;
        magnitude = trial_magnitude;
        residual = trial_residual;
        accepted = true;
        break;
      }
      ++summary.line_search_steps;
      alpha *= 0.5;
    }
    ++summary.iterations;
    if (!accepted) {
      // Restore the Hessian of the current point for a caller that inspects it.
      Assemble<D>(springs, force, u, &gradient_, true, false, nullptr);
      break;
    }
  }
  summary.final_residual = residual / force_scale;
  return summary;
}

template double EquilibriumSolver::Assemble<2>(const ActiveSprings&, const Vector&, const Vector&,
                                               Vector*, bool, bool, double*);
template double EquilibriumSolver::Assemble<3>(const ActiveSprings&, const Vector&, const Vector&,
                                               Vector*, bool, bool, double*);

}  // namespace springfit
