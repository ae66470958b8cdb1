#include "engine/probe_fit/gene_springs.h"

namespace springfit::response {
std::vector<SpringColumn> FreeColumns(const GeneSprings& springs, const SupportSystem& support) {
  const int d = springs.dimension;
  std::vector<SpringColumn> columns(static_cast<std::size_t>(springs.size()));
  for (int e = 0; e < springs.size(); ++e) {
    SpringColumn& column = columns[static_cast<std::size_t>(e)];
    const NodePair pair = springs.pairs[static_cast<std::size_t>(e)];
    for (int side = 0; side < 2; ++side) {
      const int node = side == 0 ? pair.first : pair.second;
      const double sign = side == 0 ? -1.0 : 1.0;
      for (int a = 0; a < d; ++a) {
        const int free = support.free_index()[static_cast<std::size_t>(d * node + a)];
        if (free < 0) continue;
        column.index[column.count] = free;
        column.value[column.count] = sign * springs.directions(a, e);
        ++column.count;
      }
    }
  }
  return columns;
}

GeneSprings GeneSpringsOf(const Problem& problem) {
  const SpringGeometry& geometry = problem.candidates();
  const int d = geometry.dimension;
  GeneSprings s;
  s.dimension = d;
  const int m = problem.gene_count();
  s.directions.resize(d, m);
  for (int g = 0; g < m; ++g) {
    const int c = problem.gene_candidates()[static_cast<std::size_t>(g)];
    s.pairs.push_back(geometry.pairs[static_cast<std::size_t>(c)]);
    // rest_separation is X_i - X_j: the direction from i to j is its opposite.
    s.directions.col(g) = -geometry.rest_separation.segment(d * c, d) /
                          geometry.rest_length[static_cast<std::size_t>(c)];
  }
  return s;
}

Vector Elongations(const GeneSprings& springs, const Vector& u) {
  const int d = springs.dimension;
  Vector delta(springs.size());
  for (int e = 0; e < springs.size(); ++e) {
    const NodePair pair = springs.pairs[static_cast<std::size_t>(e)];
    delta[e] =
        springs.directions.col(e).dot(u.segment(d * pair.second, d) - u.segment(d * pair.first, d));
  }
  return delta;
}

}  // namespace springfit::response
