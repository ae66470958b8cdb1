#include "engine/direct/stiffness_refinement.h"

#include <algorithm>
#include <cmath>

#include "engine/nnls.h"
#include "engine/problem/force_balance.h"

#include "engine/options_check.h"
#include "engine/sparse_columns.h"

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

}  // namespace

void RefinementOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  check.Require(max_iterations >= 0, "max_iterations", max_iterations, "value >= 0");
  check.Require(InOpenUnit(relative_tolerance), "relative_tolerance", relative_tolerance,
                "0 < value < 1");
  check.Require(initial_damping > 0.0 && std::isfinite(initial_damping), "initial_damping",
                initial_damping, "0 < value < infinity");
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

  std::vector<double> w = start;
  std::vector<Vector> u(problem.load_cases().size());
  Vector r;
  Matrix jacobian;
  const bool started =
      Equilibria(problem, w, solvers, u, r) && Jacobian(problem, w, solvers, u, jacobian);
  ThrowIfInterrupted(interruption);
  if (!started) return result;
  double f = r.squaredNorm();
  result.initial_cost = f;
  double lambda = options.initial_damping;

  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    const Vector wv = Eigen::Map<const Vector>(w.data(), genes);
    // Marquardt's scaling, with a floor so that a gene no load case moves still gets damped.
    Vector d2(genes);
    double sum_d2 = 0.0;
    for (int j = 0; j < genes; ++j) sum_d2 += d2[j] = jacobian.col(j).squaredNorm();
    const double floor_d2 = 1e-12 * std::max(sum_d2 / genes, 1e-300);
    for (int j = 0; j < genes; ++j) d2[j] = std::max(d2[j], floor_d2);
    const Vector target = jacobian * wv - r;
    bool accepted = false;
    for (int attempt = 0; attempt < 12 && !accepted; ++attempt) {
      ThrowIfInterrupted(interruption);
      // [J; sqrt(lambda) D] w' = [J w - r; sqrt(lambda) D w], w' >= 0.
      Matrix stacked(jacobian.rows() + genes, genes);
      stacked.topRows(jacobian.rows()) = jacobian;
      stacked.bottomRows(genes) = (lambda * d2).cwiseSqrt().asDiagonal();
      Vector rhs(jacobian.rows() + genes);
      rhs.head(jacobian.rows()) = target;
      rhs.tail(genes) = (lambda * d2).cwiseSqrt().cwiseProduct(wv);
      const NnlsResult step = SolveDenseNnls(stacked, rhs, usable);
      std::vector<double> trial(step.x.data(), step.x.data() + genes);
      std::vector<Vector> trial_u = u;
      Vector trial_r;
      Matrix trial_jacobian;
      // The Jacobian (one solve per gene) only for a step that lowers the cost.
      if (Equilibria(problem, trial, solvers, trial_u, trial_r) && trial_r.squaredNorm() < f &&
          Jacobian(problem, trial, solvers, trial_u, trial_jacobian)) {
        const double decrease = (f - trial_r.squaredNorm()) / f;
        w = std::move(trial);
        u = std::move(trial_u);
        r = std::move(trial_r);
        jacobian = std::move(trial_jacobian);
        f = r.squaredNorm();
        lambda = std::max(lambda / 3.0, 1e-12);
        accepted = true;
        ++result.iterations;
        if (decrease < options.relative_tolerance) result.converged = true;
      } else {
        lambda *= 10.0;
      }
    }
    if (!accepted) {
      result.converged = true;  // no descent left at any damping: a (local) minimum
      break;
    }
    if (result.converged) break;
  }

  result.refined = true;
  result.weights = w;
  result.evaluation = cost.Evaluate(problem.SpringsOfWeights(w));
  ThrowIfInterrupted(interruption);
  // Standard errors from the Gauss-Newton approximation of the covariance at the optimum.
  int positive = 0;
  for (const double x : w) positive += x > 0.0;
  const double variance = f / std::max<double>(static_cast<double>(r.size()) - positive, 1.0);
  std::vector<int> columns;
  for (int j = 0; j < genes; ++j) {
    if (usable[j]) columns.push_back(j);
  }
  // Unit-norm columns, so that the regularity test does not depend on units (a stiff spring
  // moves the nodes little per unit of weight: its column is short, not dependent).
  const auto m = static_cast<Eigen::Index>(columns.size());
  Matrix sub(jacobian.rows(), m);
  Vector norms(m);
  bool zero_column = false;
  for (Eigen::Index c = 0; c < m; ++c) {
    sub.col(c) = jacobian.col(columns[static_cast<std::size_t>(c)]);
    norms[c] = sub.col(c).norm();
    zero_column = zero_column || !(norms[c] > 0.0);
    if (norms[c] > 0.0) sub.col(c) /= norms[c];
  }
  if (zero_column || m == 0) return result;
  const Matrix normal = sub.transpose() * sub;
  Eigen::LDLT<Matrix> ldlt(normal);
  const Vector pivots = ldlt.vectorD();
  bool regular = ldlt.info() == Eigen::Success;
  for (Eigen::Index i = 0; i < m && regular; ++i) regular = pivots[i] > kSingularUnitPivot;
  if (regular) {
    result.sigma.assign(genes, HUGE_VAL);
    const Matrix inverse = ldlt.solve(Matrix::Identity(m, m));
    for (Eigen::Index c = 0; c < m; ++c) {
      result.sigma[columns[static_cast<std::size_t>(c)]] =
          std::sqrt(std::max(inverse(c, c), 0.0) * variance) / norms[c];
    }
  }
  return result;
}

}  // namespace springfit
