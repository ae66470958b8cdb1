// JSON forms of an evaluation (`springfit eval --json`, proto/EVAL.md) and of a topology file
// (a list of springs, proto/SCENE.md "Topology files").
#pragma once

#include <cstdint>
#include <vector>

#include "engine/api/problem.h"
#include "proto/json_reader.h"

namespace springfit::proto {

Json EvaluationToJson(const Problem& problem, const Evaluation& evaluation);

// {"springs": [[i, j], ...]} -> candidate mask. Throws InputError naming springs[m] when a
// pair is malformed, duplicated, or not a candidate of `problem`.
std::vector<std::uint8_t> TopologyFromJson(const Problem& problem, const Json& json);
Json TopologyToJson(const Problem& problem, const std::vector<std::uint8_t>& mask);

}  // namespace springfit::proto
