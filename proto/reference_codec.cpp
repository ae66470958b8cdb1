#include "proto/reference_codec.h"

#include "proto/json_reader.h"
#include "proto/scene_codec.h"

namespace springfit::proto {

Json ReferenceSolutionToJson(const Problem& problem) {
  const Scene& s = problem.scene();
  const int d = s.dimension;
  Json positions = Json::array();
  Json cases = Json::array();
  Json load_cases = Json::array();
  for (std::size_t k = 0; k < problem.load_cases().size(); ++k) {
    const PreparedLoadCase& lc = problem.load_cases()[k];
    positions.push_back(PointsToJson(s.rest + lc.reference, d));
    double largest = 0.0;
    for (int i = 0; i < s.node_count(); ++i)
      largest = std::max(largest, lc.reference.segment(d * i, d).norm());
    const LoadCase& original = s.load_cases[k];
    if (original.tractions.empty()) {
      load_cases.push_back(LoadCaseToJson(original, d));
    } else {
      LoadCase resolved = original;
      resolved.tractions.clear();
      resolved.forces.clear();
      const FreeNodes& free = problem.free_sets()[lc.free_set];
      for (int i = 0; i < s.node_count(); ++i) {
        const Vector f = lc.force.segment(d * i, d);
        if (free.free_index[i] >= 0 && f.squaredNorm() > 0.0)
          resolved.forces.push_back({{i}, f, true, {}});
      }
      load_cases.push_back(LoadCaseToJson(resolved, d));
    }
    Json c;
    c["name"] = s.load_cases[k].name;
    if (lc.reference_solve) {
      c["iterations"] = lc.reference_solve->iterations;
      c["load_steps"] = lc.reference_solve->load_steps;
      c["residual"] = lc.reference_solve->residual;
      if (s.reference.kind == Reference::Kind::kMss) {
        c["resolution"] = NumberOrText(lc.reference_solve->resolution);
        c["stable"] = lc.reference_solve->stable;
      }
    }
    c["max_displacement"] = largest;
    cases.push_back(std::move(c));
  }
  Json out;
  out["reference"] = {{"type", "positions"}, {"positions", std::move(positions)}};
  out["load_cases"] = std::move(load_cases);
  out["solves"] = std::move(cases);
  return out;
}

}  // namespace springfit::proto
