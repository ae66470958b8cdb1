#include "engine/direct/stiffness_refinement.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "engine/linalg/nnls.h"
#include "engine/problem/force_balance.h"

#include "engine/linalg/sparse_columns.h"
#include "engine/model/equilibrium.h"
#include "engine/runtime/options_check.h"

namespace springfit {
namespace {

// The model's equilibria u (warm-started from u where given) and its residual r = u^M - u^R
// on the free coordinates (stacked by load case, free-node order, as the force balance's
// rows). False when some load case has no equilibrium.
bool Equilibria(const Problem& problem, const std::vector<double>& w,
                std::vector<EquilibriumSolver>& solvers, std::vector<Vector>& u, Vector& r) {
  const int d = problem.dimension();
  const ActiveSprings springs = problem.SpringsOfWeights(w);
  Eigen::Index rows = 0;
  for (std::size_t k = 0; k < problem.load_cases().size(); ++k) {
    const PreparedLoadCase& lc = problem.load_cases()[k];
    EquilibriumSolver& solver = solvers[lc.free_set];
    if (solver.RestMechanismModes(springs) > 0) return false;
    if (u[k].size() == 0) u[k] = lc.reference;  // warm start at the reference's equilibrium
    if (!solver.Solve(springs, lc.force, lc.prescribed, u[k]).converged()) return false;
    rows += d * problem.free_sets()[lc.free_set].count;
  }
  r.resize(rows);
  Eigen::Index begin = 0;
  for (std::size_t k = 0; k < problem.load_cases().size(); ++k) {
    const PreparedLoadCase& lc = problem.load_cases()[k];
    const FreeNodes& free = problem.free_sets()[lc.free_set];
    for (int i = 0; i < static_cast<int>(free.free_index.size()); ++i) {
      const int f = free.free_index[i];
      if (f >= 0)
        r.segment(begin + d * f, d) = u[k].segment(d * i, d) - lc.reference.segment(d * i, d);
    }
    begin += d * free.count;
  }
  return true;
}

// The Jacobian dr/dw at the equilibria u: per load case H^-1 g_j, g_j the force spring j
// exerts per unit stiffness. False when some tangent is not positive definite.
bool Jacobian(const Problem& problem, const std::vector<double>& w,
              std::vector<EquilibriumSolver>& solvers, const std::vector<Vector>& u,
              Matrix& jacobian) {
  const ActiveSprings springs = problem.SpringsOfWeights(w);
  const ForceBalance fb = AssembleForceBalance(problem, &u);
  jacobian = Matrix(fb.a);  // g_j per case; turned into H^-1 g_j block by block below
  for (std::size_t k = 0; k < problem.load_cases().size(); ++k) {
    const PreparedLoadCase& lc = problem.load_cases()[k];
    const Eigen::Index begin = fb.row_offset[k];
    const Eigen::Index size = fb.row_offset[k + 1] - begin;
    Matrix block = jacobian.middleRows(begin, size);
    if (!solvers[lc.free_set].SolveWithTangent(springs, lc.force, u[k], block)) return false;
    jacobian.middleRows(begin, size) = block;
  }
  return true;
}

// The Levenberg-Marquardt iterate: weights, their equilibria, the residual, its Jacobian and
// the cost |r|^2.
struct RefinementPoint {
  std::vector<double> w;
  std::vector<Vector> u;  // per load case (warm starts)
  Vector r;
  Matrix jacobian;
  double cost = 0.0;

  // Solves the equilibria at w and, unless the cost is not below `only_if_below`, the Jacobian.
  // False when a load case has no equilibrium, the cost is not below, or a tangent is not positive
  // definite.
  bool Linearize(const Problem& problem, std::vector<EquilibriumSolver>& solvers,
                 std::optional<double> only_if_below) {
    if (!Equilibria(problem, w, solvers, u, r)) return false;
    cost = r.squaredNorm();
    if (only_if_below && !(cost < *only_if_below)) return false;
    return Jacobian(problem, w, solvers, u, jacobian);
  }
};

// Marquardt's scaling (the squared column norms of J), with a floor so that a gene no load case
// moves still gets damped.
Vector MarquardtScaling(const Matrix& jacobian) {
  const auto genes = jacobian.cols();
  Vector d2(genes);
  double sum_d2 = 0.0;
  for (Eigen::Index j = 0; j < genes; ++j) sum_d2 += d2[j] = jacobian.col(j).squaredNorm();
  const double floor_d2 = 1e-12 * std::max(sum_d2 / static_cast<double>(genes), 1e-300);
  for (Eigen::Index j = 0; j < genes; ++j) d2[j] = std::max(d2[j], floor_d2);
  return d2;
}

// The damped Gauss-Newton step's new weights: [J; sqrt(lambda) D] w' = [J w - r; sqrt(lambda)
// D w], w' >= 0 (unusable genes held at 0).
std::vector<double> DampedStep(const RefinementPoint& at, const Vector& d2, double lambda,
                               const std::vector<bool>& usable) {
  const Matrix& jacobian = at.jacobian;
  const auto genes = jacobian.cols();
  const Vector wv = Eigen::Map<const Vector>(at.w.data(), genes);
  Matrix stacked(jacobian.rows() + genes, genes);
  stacked.topRows(jacobian.rows()) = jacobian;
  stacked.bottomRows(genes) = (lambda * d2).cwiseSqrt().asDiagonal();
  Vector rhs(jacobian.rows() + genes);
  rhs.head(jacobian.rows()) = jacobian * wv - at.r;
  rhs.tail(genes) = (lambda * d2).cwiseSqrt().cwiseProduct(wv);
  const NnlsResult step = SolveDenseNnls(stacked, rhs, usable);
  return std::vector<double>(step.x.data(), step.x.data() + genes);
}

// Standard errors from the Gauss-Newton approximation of the covariance at the optimum
// (RefinementResult::sigma); empty when J^T J over the usable genes is singular.
std::vector<double> StandardErrors(const RefinementPoint& at, const std::vector<bool>& usable) {
  const Matrix& jacobian = at.jacobian;
  const auto genes = static_cast<int>(jacobian.cols());
  int positive = 0;
  for (const double x : at.w) positive += x > 0.0;
  const double variance =
      at.cost / std::max<double>(static_cast<double>(at.r.size()) - positive, 1.0);
  std::vector<int> columns;
  for (int j = 0; j < genes; ++j) {
    if (usable[j]) columns.push_back(j);
  }
  // Unit-norm columns, so that the regularity test does not depend on units (a stiff spring
  // moves the nodes little per unit of weight: its column is short, not dependent).
  const auto m = static_cast<Eigen::Index>(columns.size());
  Matrix sub(jacobian.rows(), m);
  Vector norms(m);
  for (Eigen::Index c = 0; c < m; ++c) {
    sub.col(c) = jacobian.col(columns[static_cast<std::size_t>(c)]);
    norms[c] = sub.col(c).norm();
    if (!(norms[c] > 0.0)) return {};
    sub.col(c) /= norms[c];
  }
  if (m == 0) return {};
  Eigen::LDLT<Matrix> ldlt(sub.transpose() * sub);
  if (ldlt.info() != Eigen::Success) return {};
  const Vector pivots = ldlt.vectorD();
  for (Eigen::Index i = 0; i < m; ++i) {
    if (!(pivots[i] > kSingularUnitPivot)) return {};
  }
  std::vector<double> sigma(genes, HUGE_VAL);
  const Matrix inverse = ldlt.solve(Matrix::Identity(m, m));
  for (Eigen::Index c = 0; c < m; ++c) {
    sigma[columns[static_cast<std::size_t>(c)]] =
        std::sqrt(std::max(inverse(c, c), 0.0) * variance) / norms[c];
  }
  return sigma;
}

}  // namespace

void RefinementOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  check.Require(max_iterations >= 0, "max_iterations", max_iterations, "value >= 0");
  check.Require(InOpenUnit(relative_tolerance), "relative_tolerance", relative_tolerance,
                "0 < value < 1");
  check.Require(initial_damping > 0.0 && std::isfinite(initial_damping), "initial_damping",
                initial_damping, "0 < value < infinity");
  check.Require(damping_decrease > 1.0 && std::isfinite(damping_decrease), "damping_decrease",
                damping_decrease, "1 < value < infinity");
  check.Require(damping_increase > 1.0 && std::isfinite(damping_increase), "damping_increase",
                damping_increase, "1 < value < infinity");
  check.Require(min_damping > 0.0 && min_damping <= initial_damping, "min_damping", min_damping,
                "0 < value <= initial_damping");
  check.Require(max_damping_attempts >= 1, "max_damping_attempts", max_damping_attempts,
                "value >= 1");
  check.Require(max_genes >= 0, "max_genes", max_genes, "value >= 0");
}

RefinementResult RefineWeights(const Problem& problem, const std::vector<double>& start,
                               const std::vector<bool>& usable, const RefinementOptions& options,
                               Interruption* interruption) {
  options.Validate();
  RefinementResult result;
  result.weights = start;
  const int genes = problem.gene_count();
  if (genes == 0 || genes > options.max_genes) return result;
  std::vector<EquilibriumSolver> solvers;
  for (const FreeNodes& free : problem.free_sets()) {
    solvers.emplace_back(problem.candidates(), free, problem.solver_options());
    solvers.back().set_interruption(interruption);
  }
  CostFunction cost(problem);
  cost.set_interruption(interruption);
  // An interrupted solve reads as a failed one: every failure checks the interruption first.

  RefinementPoint at;
  at.w = start;
  at.u.resize(problem.load_cases().size());
  const bool started = at.Linearize(problem, solvers, /*only_if_below=*/std::nullopt);
  ThrowIfInterrupted(interruption);
  if (!started) return result;
  result.initial_cost = at.cost;
  double lambda = options.initial_damping;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    const Vector d2 = MarquardtScaling(at.jacobian);
    bool accepted = false;
    for (int attempt = 0; attempt < options.max_damping_attempts && !accepted; ++attempt) {
      ThrowIfInterrupted(interruption);
      RefinementPoint trial;
      trial.w = DampedStep(at, d2, lambda, usable);
      trial.u = at.u;
      // The Jacobian (one solve per gene) only for a step that lowers the cost.
      if (trial.Linearize(problem, solvers, /*only_if_below=*/at.cost)) {
        const double decrease = (at.cost - trial.cost) / at.cost;
        at = std::move(trial);
        lambda = std::max(lambda / options.damping_decrease, options.min_damping);
        accepted = true;
        ++result.iterations;
        if (decrease < options.relative_tolerance) result.converged = true;
      } else {
        lambda *= options.damping_increase;
      }
    }
    if (!accepted) {
      result.converged = true;  // no descent left at any damping: a (local) minimum
      break;
    }
    if (result.converged) break;
  }

  result.refined = true;
  result.weights = at.w;
  result.evaluation = cost.Evaluate(problem.SpringsOfWeights(at.w));
  ThrowIfInterrupted(interruption);
  result.sigma = StandardErrors(at, usable);
  return result;
}

}  // namespace springfit
