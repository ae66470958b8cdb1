#include "engine/fem/traction.h"

#include <algorithm>
#include <map>

#include "engine/fem/fem_model.h"
#include "engine/runtime/input_error.h"

namespace springfit::fem {

std::vector<std::vector<int>> BoundaryFacets(const FemReference& fem, int dimension) {
  std::map<std::vector<int>, int> count;
  ForEachFacet(fem, dimension,
               [&](std::size_t, const std::vector<int>& facet, int) { ++count[facet]; });
  std::vector<std::vector<int>> boundary;
  for (const auto& [facet, n] : count) {
    if (n == 1) boundary.push_back(facet);
  }
  return boundary;
}

void AddTractionForces(const Scene& s, const Traction& t, const std::string& path, Vector& force) {
  const int d = s.dimension;
  std::vector<bool> in_set(s.node_count(), false);
  for (int node : t.nodes) in_set[node] = true;
  std::vector<std::vector<int>> facets;
  std::vector<double> measure;
  double total_measure = 0.0;
  for (std::vector<int>& facet : BoundaryFacets(s.reference.fem, d)) {
    if (!std::all_of(facet.begin(), facet.end(), [&](int node) { return in_set[node]; })) continue;
    const Vector a = s.rest.segment(d * facet[0], d);
    const Vector b = s.rest.segment(d * facet[1], d);
    double m = 0.0;
    if (d == 2) {
      m = (b - a).norm();
    } else {
      const Eigen::Vector3d c = s.rest.segment<3>(3 * facet[2]);
      m = 0.5 * (Eigen::Vector3d(b) - Eigen::Vector3d(a)).cross(c - Eigen::Vector3d(a)).norm();
    }
    facets.push_back(std::move(facet));
    measure.push_back(m);
    total_measure += m;
  }
  if (facets.empty() || !(total_measure > 0.0)) {
    throw InputError(
        path + ".on",
        "node set '" + t.on + "' holds no boundary " + (d == 2 ? "edge" : "face") +
            " of the mesh (a traction acts on edges or faces whose nodes are all in the set)");
  }
  const Vector density = t.total ? Vector(t.value / total_measure) : t.value;
  for (std::size_t f = 0; f < facets.size(); ++f) {
    for (int node : facets[f]) force.segment(d * node, d) += density * (measure[f] / d);
  }
}

}  // namespace springfit::fem
