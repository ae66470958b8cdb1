// Which spring weights the scene's load cases can tell apart, before any search.
//
// From the force balance at the reference's equilibria (engine/problem/force_balance.h):
//  - unseen springs: no load case changes their length, so their column of A is zero and no
//    data says anything about them;
//  - dependent groups: springs whose columns are linearly dependent, so that different
//    weights (topologies) balance the same forces in every load case. The groups are the
//    connected components of the fundamental circuits of A's columns (relative to the basis
//    a column-pivoted QR chooses): two springs share a group when some dependency involves
//    both, and the partition does not depend on the basis chosen.
//  - for each group, a suggested extra load case that separates it: among single nodal
//    forces on the group's free nodes along each axis, applied with the constraints of an
//    existing load case, the one whose small-load response gives the group's columns the
//    most independent new rows. Tried on the reference MSS in the linear (small-load) limit;
//    for a positions reference no model exists to try loads on, so there is no suggestion.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "engine/problem/force_balance.h"
#include "engine/problem/problem.h"

namespace springfit {

struct IdentifiabilityOptions {
  // Columns count as dependent when the QR's diagonal falls below this fraction of its
  // largest entry (unit-norm columns). Unit-free.
  double rank_tolerance = 1e-9;
  // A coefficient of a fundamental circuit below this (relative to its largest) is not part
  // of it.
  double circuit_tolerance = 1e-8;
  double unseen_strain = kUnseenStrain;
  // Dense QR of A over the seen genes (A has genes columns and a row per free coordinate and
  // load case): about 0.1 s at kidney-2d's 461 genes; larger scenes get no group analysis.
  int max_genes = 600;
  // A group gets a suggestion when its springs times its dependencies stay below this: each
  // trial load multiplies a block of that size (a one-load-case 30x30 grid would take minutes).
  int max_suggestion_size = 5000;

  // Throws std::invalid_argument naming the field, its value and the rule it breaks.
  void Validate() const;
};

struct LoadSuggestion {
  int node = -1;
  int axis = 0;            // 0 = x, 1 = y, 2 = z
  int constraints_of = 0;  // the load case whose fixed and prescribed nodes it keeps
  int separated = 0;       // of the group's dependencies, how many it removes
  std::string text;        // for people
};

struct DependentGroup {
  std::vector<NodePair> springs;
  int dependencies = 0;  // the group's nullity: independent combinations not seen
  std::optional<LoadSuggestion> suggestion;
};

struct IdentifiabilityReport {
  std::vector<NodePair> unidentifiable;  // both nodes constrained in every case (Problem)
  std::vector<NodePair> unseen;          // no length change in any case
  bool groups_analysed = false;          // false beyond max_genes
  int rank = 0;                          // of A over the seen genes
  std::vector<DependentGroup> groups;
};

// The words `check`, the dashboard and the exports use for groups that were not analysed:
// "not analysed (more than 600 seen genes)".
inline std::string GroupsNotAnalysedText() {
  return "not analysed (more than " + std::to_string(IdentifiabilityOptions{}.max_genes) +
         " seen genes)";
}

IdentifiabilityReport AnalyseIdentifiability(const Problem& problem,
                                             const IdentifiabilityOptions& options = {});
// The default analysis of a prepared problem, computed once on first use (thread-safe) and kept
// with it: every run on the problem reports it without redoing the QR.
const IdentifiabilityReport& Identifiability(const Problem& problem);

}  // namespace springfit
