#include "engine/fem/fem_equilibrium.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "engine/linalg/newton_iteration.h"
#include "engine/runtime/number_text.h"
#include "engine/runtime/options_check.h"

namespace springfit::fem {
namespace {

// A gradient's largest entry (the force residual), 0 for none.
double LargestEntry(const Vector& v) {
  return v.size() ? v.cwiseAbs().maxCoeff() : 0.0;
}

// Shifts of the Jacobi-scaled tangent tried in turn where it is not positive definite: a
// Levenberg-like regularisation that keeps the Newton direction a descent direction.
constexpr double kShifts[] = {0.0, 1e-10, 1e-7, 1e-4, 1e-2, 1e-1, 1.0, 10.0};
// The shift of the scaled rest stiffness when its pivots are counted: keeps an exact zero
// pivot from stopping the sparse LDLT, and is far below any step's precision.
constexpr double kRestShift = 1e-13;

std::string Fraction(double f) {
  return NumberText(100.0 * f, 4) + "%";
}

}  // namespace

void FemSolverOptions::Validate() const {
  const OptionsCheck check("FemSolverOptions");
  CheckNewtonSettings(check, *this);
  check.Require(max_load_cuts >= 0 && max_load_cuts <= 40, "max_load_cuts", max_load_cuts,
                "0 <= value <= 40");
  check.Require(max_load_steps >= 1, "max_load_steps", max_load_steps, "value >= 1");
  check.Require(supernodal_min_dofs >= 0, "supernodal_min_dofs", supernodal_min_dofs, "value >= 0");
}

FemEquilibriumSolver::FemEquilibriumSolver(const FemModel& model, FreeNodes free_nodes,
                                           FemSolverOptions options)
    : model_(&model), free_(std::move(free_nodes)), options_(options), dim_(model.dimension()) {
  options_.Validate();
  const int d = dim_;
  const int corners = d + 1;
  const int per_element = corners * corners * d * d;
  const int elements = model.element_count();
  auto element_node = [&](int e, int a) {
    return d == 2 ? model.elements2()[e].nodes[a] : model.elements3()[e].nodes[a];
  };
  // Every lower-triangle entry (r, c) of every element's free-free blocks, with its position
  // in the element's slot table.
  auto for_each_entry = [&](auto&& visit) {
    for (int e = 0; e < elements; ++e) {
      for (int a = 0; a < corners; ++a) {
        const int fa = free_.free_index[element_node(e, a)];
        for (int b = 0; b < corners; ++b) {
          const int fb = free_.free_index[element_node(e, b)];
          if (fa < 0 || fb < 0) continue;
          for (int i = 0; i < d; ++i) {
            for (int k = 0; k < d; ++k) {
              const int r = d * fa + i, c = d * fb + k;
              if (r >= c)
                visit(
                    static_cast<std::size_t>(e) * per_element + ((a * corners + b) * d + i) * d + k,
                    r, c);
            }
          }
        }
      }
    }
  };
  std::vector<std::pair<int, int>> lower;
  lower.reserve(static_cast<std::size_t>(elements) * per_element / 2);
  for_each_entry([&](std::size_t, int r, int c) { lower.emplace_back(r, c); });
  system_ = SymmetricSystem(d * free_.count, std::move(lower),
                            d * free_.count > options_.supernodal_min_dofs
                                ? SymmetricSystem::Backend::kSupernodal
                                : SymmetricSystem::Backend::kSparse);
  slots_.assign(static_cast<std::size_t>(elements) * per_element, -1);
  for_each_entry([&](std::size_t at, int r, int c) { slots_[at] = system_.Slot(r, c); });
  extent_ = BoundingBox::Of(d, model.rest()).Diagonal();
}

template <int D>
double FemEquilibriumSolver::Assemble(const Vector& force, double load, const Vector& u,
                                      Vector* gradient, bool hessian, double* magnitude) {
  constexpr int kCorners = D + 1;
  constexpr int kPerElement = kCorners * kCorners * D * D;
  const auto& elements = [&]() -> const std::vector<Element<D>>& {
    if constexpr (D == 2) {
      return model_->elements2();
    } else {
      return model_->elements3();
    }
  }();
  const auto& laws = [&]() -> const std::vector<MaterialLaw<D>>& {
    if constexpr (D == 2) {
      return model_->laws2();
    } else {
      return model_->laws3();
    }
  }();
  if (gradient) gradient->setZero(D * free_.count);
  if (hessian) system_.SetZero();
  double* values = system_.values();
  double energy = 0.0;
  double mag = 0.0;
  for (std::size_t e = 0; e < elements.size(); ++e) {
    const Element<D>& el = elements[e];
    const MaterialResponse<D> r = laws[el.law].Evaluate(DisplacementGradient(el, u), hessian);
    if (!r.admissible) {
      if (magnitude) *magnitude = std::numeric_limits<double>::infinity();
      return std::numeric_limits<double>::infinity();
    }
    energy += el.volume * r.energy;
    mag += el.volume * std::abs(r.energy);
    if (gradient) {
      // dE/du_a = V0 P G_a
      const Eigen::Matrix<double, D, kCorners> nodal =
          el.volume * r.stress * el.gradients.transpose();
      for (int a = 0; a < kCorners; ++a) {
        const int fa = free_.free_index[el.nodes[a]];
        if (fa >= 0) gradient->segment<D>(D * fa) += nodal.col(a);
      }
    }
    if (hessian) {
      // K_ab(i, k) = V0 sum_JL A(i + D J, k + D L) G_a(J) G_b(L): first contract J with G_a.
      const int* slot = &slots_[e * kPerElement];
      for (int a = 0; a < kCorners; ++a) {
        if (free_.free_index[el.nodes[a]] < 0) continue;
        // rows i, columns (k, L): sum_J A(i + D J, k + D L) G_a(J)
        Eigen::Matrix<double, D, D* D> ag = Eigen::Matrix<double, D, D * D>::Zero();
        for (int J = 0; J < D; ++J)
          ag += el.gradients(a, J) * r.tangent.template middleRows<D>(D * J);
        for (int b = 0; b < kCorners; ++b) {
          if (free_.free_index[el.nodes[b]] < 0) continue;
          for (int i = 0; i < D; ++i) {
            for (int k = 0; k < D; ++k) {
              const int s = slot[((a * kCorners + b) * D + i) * D + k];
              if (s < 0) continue;
              double v = 0.0;
              for (int L = 0; L < D; ++L) v += ag(i, k + D * L) * el.gradients(b, L);
              values[s] += el.volume * v;
            }
          }
        }
      }
    }
  }
  // External work on the free nodes.
  for (int node = 0; node < static_cast<int>(free_.free_index.size()); ++node) {
    const int f = free_.free_index[node];
    if (f < 0) continue;
    const double work = load * force.segment<D>(D * node).dot(u.segment<D>(D * node));
    energy -= work;
    mag += std::abs(work);
    if (gradient) gradient->segment<D>(D * f) -= load * force.segment<D>(D * node);
  }
  if (magnitude) *magnitude = mag;
  return energy;
}

double FemEquilibriumSolver::Energy(const Vector& force, double load, const Vector& u,
                                    Vector* gradient, bool hessian, double* magnitude) {
  return dim_ == 2 ? Assemble<2>(force, load, u, gradient, hessian, magnitude)
                   : Assemble<3>(force, load, u, gradient, hessian, magnitude);
}

double FemEquilibriumSolver::EnergyAndGradient(const Vector& force, const Vector& u,
                                               Vector* gradient, bool hessian) {
  return Energy(force, 1.0, u, gradient, hessian, nullptr);
}

int FemEquilibriumSolver::RestFreeModes() {
  const Vector zero = Vector::Zero(dim_ * model_->node_count());
  Energy(zero, 0.0, zero, nullptr, true, nullptr);
  // The stiffness scale: the largest diagonal entry of the rest tangent.
  stiffness_scale_ = 0.0;
  for (int r = 0; r < system_.size(); ++r) {
    stiffness_scale_ = std::max(stiffness_scale_, std::abs(system_.values()[system_.Slot(r, r)]));
  }
  // A tiny shift keeps an exact zero pivot from stopping the sparse LDLT (equilibrium.h).
  const int modes = system_.Factorize(kRestShift, options_.pivot_tolerance, true).small_pivots;
  rest_factor_valid_ = modes == 0;
  return modes;
}

// Newton's steps (newton_iteration.h) on the solver's state, at one load level.
struct FemEquilibriumSolver::NewtonSteps {
  FemEquilibriumSolver& solver;
  const Vector& force;
  double load;
  double tolerance;
  Vector& u;
  FemSolveSummary& summary;
  bool converged = false;

  // A linear material's tangent is the rest stiffness, already factorised: no need to assemble
  // it.
  bool NeedTangent() const { return !(solver.model_->linear() && solver.rest_factor_valid_); }

  const char* StopBeforeStep(int iterations, const EnergyPoint& at) {
    summary.final_residual = at.residual;
    if (at.residual <= tolerance) {
      converged = true;
      return "";
    }
    if (iterations >= solver.options_.max_iterations) return "the Newton iteration limit";
    ThrowIfInterrupted(solver.interruption_);
    return nullptr;
  }

  const char* Direction(double& slope) {
    // The rest stiffness's factor (RestFreeModes) serves the first step from rest, and every
    // step of a linear material, whose tangent is the same everywhere.
    bool factorised = solver.rest_factor_valid_ && (solver.model_->linear() || u.isZero());
    solver.rest_factor_valid_ = solver.rest_factor_valid_ && solver.model_->linear();
    for (const double shift : kShifts) {
      if (factorised) break;
      if (solver.system_.Factorize(shift, solver.options_.pivot_tolerance, false)
              .positive_definite) {
        factorised = true;
        break;
      }
    }
    if (!factorised) return "the tangent stayed indefinite after regularisation";
    solver.step_ = -solver.gradient_;
    solver.system_.Solve(solver.step_);
    slope = solver.gradient_.dot(solver.step_);
    if (!(slope < 0.0)) return "the Newton step is not a descent direction";
    return nullptr;
  }

  // The energy alone at each trial (the FEM's assembly is the costly part).
  EnergyPoint Trial(double alpha) {
    const int d = solver.dim_;
    solver.trial_ = u;
    for (int node = 0; node < static_cast<int>(solver.free_.free_index.size()); ++node) {
      const int f = solver.free_.free_index[node];
      if (f >= 0) solver.trial_.segment(d * node, d) += alpha * solver.step_.segment(d * f, d);
    }
    EnergyPoint trial;
    trial.energy = solver.Energy(force, load, solver.trial_, nullptr, false, &trial.magnitude);
    return trial;
  }

  // The accepted point again, with its gradient (and the tangent the next step needs).
  const char* Accept(EnergyPoint& point) {
    u.swap(solver.trial_);
    point.energy =
        solver.Energy(force, load, u, &solver.gradient_, NeedTangent(), &point.magnitude);
    if (!std::isfinite(point.energy)) return "the energy is not finite";
    point.residual = LargestEntry(solver.gradient_);
    return nullptr;
  }

  void Reject() {}
};

bool FemEquilibriumSolver::Newton(const Vector& force, double load, double tolerance, Vector& u,
                                  FemSolveSummary& summary) {
  EnergyPoint at;
  NewtonSteps steps{*this, force, load, tolerance, u, summary};
  at.energy = Energy(force, load, u, &gradient_, steps.NeedTangent(), &at.magnitude);
  if (!std::isfinite(at.energy)) return false;
  at.residual = LargestEntry(gradient_);
  const LineSearchOptions search{options_.armijo, options_.max_line_search_steps,
                                 RoundoffRule::kSlack};
  int iterations = 0;
  // (Why it stopped is not kept: a load level that fails is cut back, and Solve's message says
  // how far the load got.)
  static_cast<void>(NewtonIterate(steps, at, search, iterations));
  summary.iterations += iterations;
  return steps.converged;
}

FemSolveSummary FemEquilibriumSolver::Solve(const Vector& force, const Vector& prescribed,
                                            Vector& u) {
  FemSolveSummary summary;
  const int d = dim_;
  const int n = model_->node_count();
  u = Vector::Zero(d * n);
  // Once per solver (the constrained nodes fix the rest stiffness): load cases sharing these
  // free nodes reuse the count, and with a linear material the factor too.
  if (!rest_modes_) rest_modes_ = RestFreeModes();
  summary.free_modes = *rest_modes_;
  if (summary.free_modes > 0) {
    summary.termination = FemTermination::kFreeModes;
    summary.message = std::to_string(summary.free_modes) +
                      " free modes at rest: part of the mesh is not held by the constrained nodes";
    return summary;
  }
  double largest_force = 0.0, largest_prescribed = 0.0;
  for (int node = 0; node < n; ++node) {
    if (free_.free_index[node] >= 0) {
      largest_force = std::max(largest_force, force.segment(d * node, d).cwiseAbs().maxCoeff());
    } else {
      largest_prescribed =
          std::max(largest_prescribed, prescribed.segment(d * node, d).cwiseAbs().maxCoeff());
    }
  }
  const double force_scale = std::max(largest_force, stiffness_scale_ * largest_prescribed);
  const double tolerance = std::max(options_.relative_force_tolerance * force_scale,
                                    options_.roundoff_force_tolerance * stiffness_scale_ * extent_);
  const double smallest_increment = std::ldexp(1.0, -options_.max_load_cuts);

  double level = 0.0;
  double increment = 1.0;
  Vector trial;
  bool converged = false;
  for (int attempt = 0; attempt < options_.max_load_steps; ++attempt) {
    const double target = std::min(1.0, level + increment);
    trial = u;
    for (int node = 0; node < n; ++node) {
      if (free_.free_index[node] < 0)
        trial.segment(d * node, d) = target * prescribed.segment(d * node, d);
    }
    if (Newton(force, target, tolerance, trial, summary)) {
      u.swap(trial);
      level = target;
      ++summary.load_steps;
      if (level >= 1.0) {
        converged = true;
        break;
      }
      increment = std::min(2.0 * increment, 1.0 - level);
    } else {
      ++summary.load_cuts;
      increment *= 0.5;
      if (increment < smallest_increment) break;
    }
  }
  summary.reached = level;
  summary.final_residual =
      force_scale > 0.0 ? summary.final_residual / force_scale : summary.final_residual;
  if (!converged) {
    summary.termination = FemTermination::kNoEquilibrium;
    summary.message =
        "no equilibrium found beyond " + Fraction(level) + " of the load (" +
        std::to_string(summary.load_steps) + " load steps, " + std::to_string(summary.load_cuts) +
        " cut back): an instability such as buckling, or a load beyond what the material "
        "carries; try a smaller load";
    return summary;
  }
  summary.inverted_element = model_->FirstInvertedElement(u);
  if (summary.inverted_element >= 0) {
    summary.termination = FemTermination::kInverted;
    summary.message =
        "element " + std::to_string(summary.inverted_element) +
        " is inverted (J <= 0) at the equilibrium: the load is too large for this model";
    return summary;
  }
  summary.termination = FemTermination::kConverged;
  return summary;
}

}  // namespace springfit::fem
