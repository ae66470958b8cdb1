#include "proto/evaluation_codec.h"

#include "engine/api/input_error.h"
#include "proto/names.h"

namespace springfit::proto {

Json EvaluationToJson(const Problem& problem, const Evaluation& e) {
  Json j;
  j["cost"] = e.cost;
  j["normalized_error"] = e.normalized_error;
  j["mechanism"] = e.mechanism;
  j["converged"] = e.converged;
  j["mechanism_modes"] = e.mechanism_modes;
  Json cases = Json::array();
  for (std::size_t k = 0; k < e.load_cases.size(); ++k) {
    const LoadCaseEvaluation& lc = e.load_cases[k];
    Json c;
    c["name"] = problem.scene().load_cases[k].name;
    c["cost"] = lc.cost;
    c["normalized_error"] = lc.normalized_error;
    c["termination"] = TerminationName(lc.solve.termination);
    c["iterations"] = lc.solve.iterations;
    c["projected_steps"] = lc.solve.projected_steps;
    c["line_search_steps"] = lc.solve.line_search_steps;
    c["initial_residual"] = lc.solve.initial_residual;
    c["residual"] = lc.solve.final_residual;
    c["mechanism_modes"] = lc.solve.mechanism_modes;
    c["near_mechanism_modes"] = lc.solve.near_mechanism_modes;
    cases.push_back(std::move(c));
  }
  j["load_cases"] = std::move(cases);
  return j;
}

std::vector<std::uint8_t> TopologyFromJson(const Problem& problem, const Json& json) {
  ExpectKeys(json, "", {"springs"});
  if (!json.contains("springs")) throw InputError("springs", "required");
  const Json& springs = json["springs"];
  ExpectArray(springs, "springs");
  std::vector<std::uint8_t> mask(problem.candidates().size(), 0);
  for (std::size_t m = 0; m < springs.size(); ++m) {
    const std::string p = IndexPath("springs", m);
    ExpectArray(springs[m], p);
    if (springs[m].size() != 2) throw InputError(p, "expected a pair [i, j]");
    const int a = ReadInt(springs[m][0], IndexPath(p, 0));
    const int b = ReadInt(springs[m][1], IndexPath(p, 1));
    const int c = problem.CandidateIndex({std::min(a, b), std::max(a, b)});
    if (c < 0) {
      throw InputError(p, "(" + std::to_string(a) + ", " + std::to_string(b) +
                              ") is not a candidate spring of the scene");
    }
    if (mask[c]) throw InputError(p, "duplicate spring");
    mask[c] = 1;
  }
  return mask;
}

Json TopologyToJson(const Problem& problem, const std::vector<std::uint8_t>& mask) {
  Json springs = Json::array();
  for (int c = 0; c < problem.candidates().size(); ++c) {
    if (mask[c])
      springs.push_back(
          {problem.candidates().pairs[c].first, problem.candidates().pairs[c].second});
  }
  Json j;
  j["springs"] = std::move(springs);
  return j;
}

}  // namespace springfit::proto
