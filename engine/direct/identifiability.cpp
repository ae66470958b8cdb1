#include "engine/direct/identifiability.h"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <optional>

#include "engine/linalg/column_dependencies.h"
#include "engine/linalg/sparse_columns.h"
#include "engine/problem/force_balance.h"
#include "engine/problem/rest_stiffness.h"
#include "engine/problem/support_system.h"

#include "engine/runtime/options_check.h"

namespace springfit {
namespace {

// Rank of `m` relative to its largest singular value.
int NumericalRank(const Matrix& m, double tolerance) {
  if (m.size() == 0) return 0;
  Eigen::ColPivHouseholderQR<Matrix> qr(m);
  qr.setThreshold(tolerance);
  return static_cast<int>(qr.rank());
}

constexpr const char* kAxisNames[] = {"x", "y", "z"};

// The nodes of a group's springs, in order.
std::vector<int> NodesOfGenes(const Problem& problem, const std::vector<int>& genes) {
  std::vector<int> nodes;
  for (const int g : genes) {
    const NodePair p = problem.candidates().pairs[problem.gene_candidates()[g]];
    nodes.push_back(p.first);
    nodes.push_back(p.second);
  }
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  return nodes;
}

// The force-balance block of the group's genes in a load case whose free displacements are
// `u` (stacked by free node), to first order: each spring's force per unit stiffness.
Matrix GroupBlock(const Problem& problem, const std::vector<int>& genes, const FreeNodes& free,
                  const Eigen::Ref<const Vector>& u) {
  const int d = problem.dimension();
  const SpringGeometry& candidates = problem.candidates();
  Matrix block = Matrix::Zero(static_cast<Eigen::Index>(d) * free.count,
                              static_cast<Eigen::Index>(genes.size()));
  auto displacement = [&](int node) {
    Vector at = Vector::Zero(d);
    if (free.free_index[node] >= 0) at = u.segment(d * free.free_index[node], d);
    return at;
  };
  for (std::size_t j = 0; j < genes.size(); ++j) {
    const int cand = problem.gene_candidates()[genes[j]];
    const NodePair p = candidates.pairs[cand];
    const Vector unit =
        candidates.rest_separation.segment(d * cand, d) / candidates.rest_length[cand];
    const double stretch = unit.dot(displacement(p.first) - displacement(p.second));
    const auto col = static_cast<Eigen::Index>(j);
    if (free.free_index[p.first] >= 0)
      block.col(col).segment(d * free.free_index[p.first], d) -= stretch * unit;
    if (free.free_index[p.second] >= 0)
      block.col(col).segment(d * free.free_index[p.second], d) += stretch * unit;
  }
  return block;
}

// How many of the group's dependencies (`group_null`) a load case with this block removes.
int Separated(const Matrix& block, const Matrix& group_null, double tolerance) {
  const Matrix seen = block * group_null;
  const double scale = block.norm() * group_null.norm();
  if (!(scale > 0.0) || !(seen.norm() > tolerance * scale)) return 0;
  return NumericalRank(seen / seen.norm(), tolerance);
}

// The reference's small-load response under the scene's supports: its stiffness at rest (the
// FEM model's or the reference springs', rest_stiffness.h) factorised on a free set's degrees of
// freedom (support_system.h: the probe fit's factorisation, its pivots tested on the scaled
// matrix), once per free set, and only when a group asks for a suggestion there. The free
// degrees of freedom come node by node, as a FreeNodes numbers them.
class ReferenceRestResponse {
 public:
  explicit ReferenceRestResponse(const Problem& problem) : problem_(problem) {}

  // The factorisation on free set `s`; nullptr where the reference is not held there.
  const response::SupportSystem* Factor(int s) {
    if (const auto at = systems_.find(s); at != systems_.end()) return at->second.get();
    if (!stiffness_) stiffness_ = ReferenceRestStiffness(problem_);
    const FreeNodes& free = problem_.free_sets()[static_cast<std::size_t>(s)];
    std::vector<bool> constrained(free.free_index.size());
    for (std::size_t node = 0; node < constrained.size(); ++node)
      constrained[node] = free.free_index[node] < 0;
    auto system = std::make_unique<response::SupportSystem>(problem_.dimension(), constrained);
    if (!system->Factorize(*stiffness_)) system.reset();
    return systems_.emplace(s, std::move(system)).first->second.get();
  }

 private:
  const Problem& problem_;
  std::optional<SparseMatrix> stiffness_;
  std::map<int, std::unique_ptr<response::SupportSystem>> systems_;
};

// The suggestion for one group (an MSS or FEM reference; none for positions): see
// identifiability.h.
std::optional<LoadSuggestion> SuggestLoad(const Problem& problem,
                                          const std::vector<int>& group_genes,
                                          const Matrix& group_null,
                                          const IdentifiabilityOptions& options,
                                          ReferenceRestResponse& reference,
                                          Interruption* interruption) {
  const Scene& scene = problem.scene();
  if (scene.reference.kind == Reference::Kind::kPositions) return std::nullopt;
  const int d = problem.dimension();
  const std::vector<int> nodes = NodesOfGenes(problem, group_genes);
  std::optional<LoadSuggestion> best;
  for (std::size_t c = 0; c < problem.load_cases().size(); ++c) {
    ThrowIfInterrupted(interruption);
    const int free_set = problem.load_cases()[c].free_set;
    const FreeNodes& free = problem.free_sets()[static_cast<std::size_t>(free_set)];
    // One unit force per (group node free in this case, axis): their small-load responses
    // from one factorisation of the reference's rest stiffness.
    std::vector<std::pair<int, int>> trials;
    for (const int node : nodes) {
      if (free.free_index[node] < 0) continue;
      for (int a = 0; a < d; ++a) trials.emplace_back(node, a);
    }
    if (trials.empty()) continue;
    const response::SupportSystem* system = reference.Factor(free_set);
    if (system == nullptr) continue;
    Matrix response = Matrix::Zero(static_cast<Eigen::Index>(d) * free.count,
                                   static_cast<Eigen::Index>(trials.size()));
    for (std::size_t t = 0; t < trials.size(); ++t) {
      response(d * free.free_index[trials[t].first] + trials[t].second,
               static_cast<Eigen::Index>(t)) = 1.0;
    }
    system->SolveColumns(response);
    for (std::size_t t = 0; t < trials.size(); ++t) {
      const Matrix block =
          GroupBlock(problem, group_genes, free, response.col(static_cast<Eigen::Index>(t)));
      const int separated = Separated(block, group_null, options.dependencies.circuit_tolerance);
      if (separated > 0 && (!best || separated > best->separated))
        best =
            LoadSuggestion{trials[t].first, trials[t].second, static_cast<int>(c), separated, ""};
    }
  }
  if (best) {
    const std::string& name = scene.load_cases[best->constraints_of].name;
    best->text = "add a load case with a force on " + NodesNamed(scene, {best->node}) + " along " +
                 kAxisNames[best->axis] + ", with the constraints of load case " +
                 std::to_string(best->constraints_of) + (name.empty() ? "" : " ('" + name + "')") +
                 ": it separates " + std::to_string(best->separated) + " of " +
                 std::to_string(group_null.cols()) + " dependencies";
  }
  return best;
}

// The columns `seen` of `a`, each scaled to unit norm (the QR's tolerance is then unit-free).
SparseMatrix UnitColumns(const SparseMatrix& a, const std::vector<int>& seen) {
  SparseMatrix out = SelectColumns(a, seen);
  for (Eigen::Index j = 0; j < out.cols(); ++j) out.col(j) /= out.col(j).norm();
  return out;
}

// The dependent groups: columns that share a fundamental circuit, joined (connected
// components), each group's columns in order and the groups in order of their first column.
std::vector<std::vector<int>> GroupsOfCircuits(const ColumnDependencies& dependencies) {
  std::map<int, int> parent;  // only the columns of some circuit
  auto find = [&](int i) {
    while (parent.at(i) != i) i = parent[i] = parent.at(parent.at(i));
    return i;
  };
  for (const ColumnDependencies::Circuit& circuit : dependencies.circuits) {
    parent.emplace(circuit.column, circuit.column);
    for (const auto& [column, coefficient] : circuit.basis) {
      parent.emplace(column, column);
      parent[find(column)] = find(circuit.column);
    }
  }
  std::map<int, int> group_of_root;
  std::vector<std::vector<int>> groups;
  for (const auto& [column, unused] : parent) {
    const auto [at, added] = group_of_root.emplace(find(column), static_cast<int>(groups.size()));
    if (added) groups.emplace_back();
    groups[at->second].push_back(column);
  }
  return groups;
}

// A basis of the weight combinations the group's columns cannot tell apart: its fundamental
// circuits, one column each (rows: the group's columns in `members` order).
Matrix NullBasisOfGroup(const ColumnDependencies& dependencies, const std::vector<int>& members) {
  auto row = [&](int column) {
    return static_cast<Eigen::Index>(std::lower_bound(members.begin(), members.end(), column) -
                                     members.begin());
  };
  std::vector<const ColumnDependencies::Circuit*> own;
  for (const ColumnDependencies::Circuit& circuit : dependencies.circuits) {
    if (std::binary_search(members.begin(), members.end(), circuit.column)) own.push_back(&circuit);
  }
  Matrix null = Matrix::Zero(static_cast<Eigen::Index>(members.size()),
                             static_cast<Eigen::Index>(own.size()));
  for (std::size_t e = 0; e < own.size(); ++e) {
    const auto col = static_cast<Eigen::Index>(e);
    null(row(own[e]->column), col) = 1.0;
    for (const auto& [column, coefficient] : own[e]->basis) null(row(column), col) = -coefficient;
  }
  return null;
}

}  // namespace

const IdentifiabilityReport& Identifiability(const Problem& problem, Interruption* interruption) {
  std::call_once(problem.identifiability_once_, [&] {
    problem.identifiability_ = std::make_shared<const IdentifiabilityReport>(
        AnalyseIdentifiability(problem, {}, interruption));
  });
  return *problem.identifiability_;
}

void IdentifiabilityOptions::Validate() const {
  const OptionsCheck check("IdentifiabilityOptions");
  dependencies.Validate(check.Nested("dependencies"));
  check.Require(InOpenUnit(unseen_strain), "unseen_strain", unseen_strain, "0 < value < 1");
  check.Require(max_genes >= 0, "max_genes", max_genes, "value >= 0");
  check.Require(max_suggestion_size >= 0, "max_suggestion_size", max_suggestion_size, "value >= 0");
}

IdentifiabilityReport AnalyseIdentifiability(const Problem& problem,
                                             const IdentifiabilityOptions& options,
                                             Interruption* interruption) {
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
  if (static_cast<int>(seen.size()) > options.max_genes) {
    report.not_analysed = "more than " + std::to_string(options.max_genes) + " seen genes";
    return report;
  }
  const SparseMatrix a = UnitColumns(fb.a, seen);
  const ColumnDependencies dependencies =
      FindColumnDependencies(a, options.dependencies, interruption);
  report.rank = dependencies.rank;
  report.groups_analysed = dependencies.analysed;
  report.not_analysed = dependencies.not_analysed;
  if (!dependencies.analysed) return report;
  ReferenceRestResponse reference(problem);
  for (const std::vector<int>& members : GroupsOfCircuits(dependencies)) {
    DependentGroup group;
    std::vector<int> genes;
    for (const int column : members) {
      genes.push_back(seen[static_cast<std::size_t>(column)]);
      group.springs.push_back(problem.candidates().pairs[problem.gene_candidates()[genes.back()]]);
    }
    group.dependencies = static_cast<int>(std::count_if(
        dependencies.circuits.begin(), dependencies.circuits.end(), [&](const auto& circuit) {
          return std::binary_search(members.begin(), members.end(), circuit.column);
        }));
    const auto size = static_cast<long long>(genes.size()) * group.dependencies;
    if (size <= options.max_suggestion_size) {
      group.suggestion = SuggestLoad(problem, genes, NullBasisOfGroup(dependencies, members),
                                     options, reference, interruption);
    }
    report.groups.push_back(std::move(group));
  }
  return report;
}

}  // namespace springfit
