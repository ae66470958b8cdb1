#include "engine/api/model.h"

namespace springfit {

FreeNodes FreeNodes::FromConstrained(const std::vector<bool>& constrained) {
  FreeNodes f;
  f.free_index.assign(constrained.size(), -1);
  for (std::size_t node = 0; node < constrained.size(); ++node) {
    if (!constrained[node]) f.free_index[node] = f.count++;
  }
  return f;
}

}  // namespace springfit
