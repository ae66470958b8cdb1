// What the scene's load cases can tell apart (identifiability.h computes it): the report that
// check, the result and the dashboard show, and the one call that gets a problem's report,
// apart from the QR that makes it.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "engine/api/scene.h"

namespace springfit {

class Interruption;  // engine/runtime/interruption.h
class Problem;       // engine/api/problem.h

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
  // False when the groups were not analysed (too many seen genes, a rank the QR could not
  // confirm, too many dependencies to trace): then `not_analysed` says why and no group is
  // claimed.
  bool groups_analysed = false;
  std::string not_analysed;
  int rank = 0;  // of A over the seen genes
  std::vector<DependentGroup> groups;
};

// The words `check`, the dashboard and the exports use for groups that were not analysed,
// with the report's reason (`not_analysed`; empty in results written before it was kept):
// "not analysed (more than 30000 seen genes)".
inline std::string GroupsNotAnalysedText(const std::string& why) {
  return why.empty() ? "not analysed" : "not analysed (" + why + ")";
}

// The default analysis of a prepared problem, computed once on first use (thread-safe) and kept
// with it: every run on the problem reports it without redoing the QR.
// An interrupted analysis is not kept: the next call analyses again.
const IdentifiabilityReport& Identifiability(const Problem& problem,
                                             Interruption* interruption = nullptr);

}  // namespace springfit
