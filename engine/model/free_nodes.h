// Which nodes are the unknowns of a load case: every solver (the MSS's, the FEM's), the rigidity
// test and the fits index their free degrees of freedom through it.
#pragma once

#include <vector>

namespace springfit {

// free_index[node] is the node's index among the free nodes, or -1 when the node is
// constrained.
struct FreeNodes {
  std::vector<int> free_index;
  int count = 0;

  // `constrained[node]` true for fixed nodes and nodes with a prescribed displacement.
  static FreeNodes FromConstrained(const std::vector<bool>& constrained);
  friend bool operator==(const FreeNodes&, const FreeNodes&) = default;
};

}  // namespace springfit
