#include "engine/model/springs.h"

#include <algorithm>

namespace springfit {

SpringGeometry::SpringGeometry(int dim, const Vector& rest, std::vector<NodePair> p)
    : dimension(dim), pairs(std::move(p)) {
  rest_length.reserve(pairs.size());
  rest_separation.resize(dim * static_cast<Eigen::Index>(pairs.size()));
  for (std::size_t s = 0; s < pairs.size(); ++s) {
    const Vector d =
        rest.segment(dim * pairs[s].first, dim) - rest.segment(dim * pairs[s].second, dim);
    rest_separation.segment(dim * static_cast<Eigen::Index>(s), dim) = d;
    rest_length.push_back(d.norm());
  }
}

double SpringGeometry::MaxRestLength() const {
  return rest_length.empty() ? 0.0 : *std::max_element(rest_length.begin(), rest_length.end());
}

double ActiveSprings::MaxStiffness() const {
  return stiffness.empty() ? 0.0 : *std::max_element(stiffness.begin(), stiffness.end());
}

}  // namespace springfit
