#include "engine/direct/identifiability.h"

#include <Eigen/LU>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <numeric>

#include "engine/equilibrium.h"
#include "engine/problem/force_balance.h"

#include "engine/options_check.h"

namespace springfit {
namespace {

int Find(std::vector<int>& parent, int i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}

// Rank of `m` relative to its largest singular value.
int NumericalRank(const Matrix& m, double tolerance) {
  if (m.size() == 0) return 0;
  Eigen::ColPivHouseholderQR<Matrix> qr(m);
  qr.setThreshold(tolerance);
  return static_cast<int>(qr.rank());
}

constexpr const char* kAxisNames[] = {"x", "y", "z"};

// The suggestion for one group (MSS reference only): see identifiability.h.
std::optional<LoadSuggestion> SuggestLoad(const Problem& problem,
                                          const std::vector<int>& group_genes,
                                          const Matrix& group_null,
                                          const IdentifiabilityOptions& options) {
  const Scene& scene = problem.scene();
  if (scene.reference.kind != Reference::Kind::kMss) return std::nullopt;
  const int d = problem.dimension();
  const SpringGeometry reference(d, scene.rest, scene.reference.springs);
  ActiveSprings springs;
  for (int m = 0; m < reference.size(); ++m) {
    springs.index.push_back(m);
    springs.stiffness.push_back(scene.reference.stiffness.size() == 1
                                    ? scene.reference.stiffness[0]
                                    : scene.reference.stiffness[m]);
  }
  std::vector<int> nodes;
  for (const int g : group_genes) {
    const NodePair p = problem.candidates().pairs[problem.gene_candidates()[g]];
    nodes.push_back(p.first);
    nodes.push_back(p.second);
  }
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());

  std::optional<LoadSuggestion> best;
  const int n = scene.node_count();
  for (std::size_t c = 0; c < problem.load_cases().size(); ++c) {
    const FreeNodes& free = problem.free_sets()[problem.load_cases()[c].free_set];
    // One unit force per (group node free in this case, axis): their small-load responses
    // from one factorisation of the reference's rest stiffness.
    std::vector<std::pair<int, int>> trials;
    for (const int node : nodes) {
      if (free.free_index[node] < 0) continue;
      for (int a = 0; a < d; ++a) trials.emplace_back(node, a);
    }
    if (trials.empty()) continue;
    Matrix response = Matrix::Zero(static_cast<Eigen::Index>(d) * free.count,
                                   static_cast<Eigen::Index>(trials.size()));
    for (std::size_t t = 0; t < trials.size(); ++t) {
      response(d * free.free_index[trials[t].first] + trials[t].second,
               static_cast<Eigen::Index>(t)) = 1.0;
    }
    EquilibriumSolver solver(reference, free, problem.solver_options());
    const Vector zero = Vector::Zero(static_cast<Eigen::Index>(d) * n);
    if (!solver.SolveWithTangent(springs, zero, zero, response)) continue;
    for (std::size_t t = 0; t < trials.size(); ++t) {
      // The new load case's force-balance block for the group's genes, to first order.
      Matrix block = Matrix::Zero(static_cast<Eigen::Index>(d) * free.count,
                                  static_cast<Eigen::Index>(group_genes.size()));
      auto displacement = [&](int node) {
        Vector u = Vector::Zero(d);
        if (free.free_index[node] >= 0)
          u = response.col(static_cast<Eigen::Index>(t)).segment(d * free.free_index[node], d);
        return u;
      };
      for (std::size_t j = 0; j < group_genes.size(); ++j) {
        const int cand = problem.gene_candidates()[group_genes[j]];
        const NodePair p = problem.candidates().pairs[cand];
        const Vector unit = problem.candidates().rest_separation.segment(d * cand, d) /
                            problem.candidates().rest_length[cand];
        const double stretch = unit.dot(displacement(p.first) - displacement(p.second));
        const auto col = static_cast<Eigen::Index>(j);
        if (free.free_index[p.first] >= 0)
          block.col(col).segment(d * free.free_index[p.first], d) -= stretch * unit;
        if (free.free_index[p.second] >= 0)
          block.col(col).segment(d * free.free_index[p.second], d) += stretch * unit;
      }
      const Matrix seen = block * group_null;
      const double scale = block.norm() * group_null.norm();
      const int separated = scale > 0.0 && seen.norm() > options.circuit_tolerance * scale
                                ? NumericalRank(seen / seen.norm(), options.circuit_tolerance)
                                : 0;
      if (separated > 0 && (!best || separated > best->separated)) {
        LoadSuggestion s;
        s.node = trials[t].first;
        s.axis = trials[t].second;
        s.constraints_of = static_cast<int>(c);
        s.separated = separated;
        best = s;
      }
    }
  }
  if (best) {
    const std::string& name = scene.load_cases[best->constraints_of].name;
    best->text = "add a load case with a force on node " + std::to_string(best->node) + " along " +
                 kAxisNames[best->axis] + ", with the constraints of load case " +
                 std::to_string(best->constraints_of) + (name.empty() ? "" : " ('" + name + "')") +
                 ": it separates " + std::to_string(best->separated) + " of " +
                 std::to_string(group_null.cols()) + " dependencies";
  }
  return best;
}

}  // namespace

const IdentifiabilityReport& Identifiability(const Problem& problem) {
  std::call_once(problem.identifiability_once_, [&] {
    problem.identifiability_ =
        std::make_shared<const IdentifiabilityReport>(AnalyseIdentifiability(problem));
  });
  return *problem.identifiability_;
}

void IdentifiabilityOptions::Validate() const {
  const OptionsCheck check("IdentifiabilityOptions");
  check.Require(InOpenUnit(rank_tolerance), "rank_tolerance", rank_tolerance, "0 < value < 1");
  check.Require(InOpenUnit(circuit_tolerance), "circuit_tolerance", circuit_tolerance,
                "0 < value < 1");
  check.Require(InOpenUnit(unseen_strain), "unseen_strain", unseen_strain, "0 < value < 1");
  check.Require(max_genes >= 0, "max_genes", max_genes, "value >= 0");
  check.Require(max_suggestion_size >= 0, "max_suggestion_size", max_suggestion_size, "value >= 0");
}

IdentifiabilityReport AnalyseIdentifiability(const Problem& problem,
                                             const IdentifiabilityOptions& options) {
  options.Validate();
  IdentifiabilityReport report;
  for (const int c : problem.unidentifiable())
    report.unidentifiable.push_back(problem.candidates().pairs[c]);
  const ForceBalance fb = AssembleForceBalance(problem);
  std::vector<int> seen;
  const std::vector<bool> is_seen = SeenGenes(fb, options.unseen_strain);
  for (int g = 0; g < problem.gene_count(); ++g) {
    const NodePair pair = problem.candidates().pairs[problem.gene_candidates()[g]];
    if (!is_seen[g]) {
      report.unseen.push_back(pair);
    } else {
      seen.push_back(g);
    }
  }
  if (static_cast<int>(seen.size()) > options.max_genes) return report;
  report.groups_analysed = true;
  const auto n = static_cast<Eigen::Index>(seen.size());
  if (n == 0) return report;

  Matrix a(fb.a.rows(), n);
  for (Eigen::Index j = 0; j < n; ++j) {
    a.col(j) = Vector(fb.a.col(seen[static_cast<std::size_t>(j)]));
    a.col(j) /= a.col(j).norm();
  }
  Eigen::ColPivHouseholderQR<Matrix> qr(a);
  qr.setThreshold(options.rank_tolerance);
  const Eigen::Index rank = qr.rank();
  report.rank = static_cast<int>(rank);
  if (rank == n) return report;

  // Fundamental circuits: each non-basis column in terms of the basis columns.
  const auto& perm = qr.colsPermutation().indices();
  const Matrix r = qr.matrixR().topRows(rank);
  const Matrix coefficients =
      r.leftCols(rank).triangularView<Eigen::Upper>().solve(r.rightCols(n - rank));
  std::vector<int> parent(static_cast<std::size_t>(n));
  std::iota(parent.begin(), parent.end(), 0);
  std::vector<bool> dependent(static_cast<std::size_t>(n), false);
  for (Eigen::Index e = 0; e < n - rank; ++e) {
    const int column = perm[rank + e];
    dependent[column] = true;
    const double largest = std::max(coefficients.col(e).cwiseAbs().maxCoeff(), 1.0);
    for (Eigen::Index b = 0; b < rank; ++b) {
      if (std::abs(coefficients(b, e)) > options.circuit_tolerance * largest) {
        dependent[perm[b]] = true;
        parent[Find(parent, perm[b])] = Find(parent, column);
      }
    }
  }
  // Groups in order of their first gene.
  std::vector<int> group_of(static_cast<std::size_t>(n), -1);
  std::vector<std::vector<int>> members;
  for (Eigen::Index j = 0; j < n; ++j) {
    if (!dependent[j]) continue;
    const int root = Find(parent, static_cast<int>(j));
    if (group_of[root] < 0) {
      group_of[root] = static_cast<int>(members.size());
      members.emplace_back();
    }
    members[group_of[root]].push_back(seen[static_cast<std::size_t>(j)]);
  }
  for (const std::vector<int>& genes : members) {
    DependentGroup group;
    Matrix columns(a.rows(), static_cast<Eigen::Index>(genes.size()));
    for (std::size_t k = 0; k < genes.size(); ++k) {
      group.springs.push_back(problem.candidates().pairs[problem.gene_candidates()[genes[k]]]);
      const auto at = std::lower_bound(seen.begin(), seen.end(), genes[k]) - seen.begin();
      columns.col(static_cast<Eigen::Index>(k)) = a.col(at);
    }
    Eigen::FullPivLU<Matrix> lu(columns);
    lu.setThreshold(options.rank_tolerance);
    const Matrix null = lu.kernel();
    group.dependencies = lu.rank() == columns.cols() ? 0 : static_cast<int>(null.cols());
    const auto size = static_cast<long long>(genes.size()) * group.dependencies;
    if (group.dependencies > 0 && size <= options.max_suggestion_size) {
      group.suggestion = SuggestLoad(problem, genes, null, options);
    }
    report.groups.push_back(std::move(group));
  }
  return report;
}

}  // namespace springfit
