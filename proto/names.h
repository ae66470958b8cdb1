// Enum <-> string mappings of the formats, in one place.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "engine/api/analysis.h"
#include "engine/api/identify.h"
#include "engine/api/result.h"
#include "engine/api/scene.h"
#include "proto/json_reader.h"

namespace springfit::proto {

std::string_view CandidateKindName(CandidateSpec::Kind kind);
std::optional<CandidateSpec::Kind> ParseCandidateKind(std::string_view name);

std::string_view ReferenceKindName(Reference::Kind kind);
std::optional<Reference::Kind> ParseReferenceKind(std::string_view name);

// FEM reference materials and 2D modes (proto/SCENE.md, "fem").
std::string_view MaterialModelName(MaterialModel model);
std::optional<MaterialModel> ParseMaterialModel(std::string_view name);
std::string_view PlaneModeName(PlaneMode mode);
std::optional<PlaneMode> ParsePlaneMode(std::string_view name);

std::string_view TerminationName(Termination termination);

// Search strategies (proto/SCENE.md, "search").
std::string_view StrategyName(Strategy strategy);
std::optional<Strategy> ParseStrategy(std::string_view name);
// ParseStrategy, or InputError(path, "unknown strategy 'x' (expected default, paper, direct,
// hybrid or continuous)").
Strategy StrategyFromName(const std::string& name, const std::string& path);
std::string_view StopReasonName(StopReason reason);

// What an identification finds (proto/SCENE.md, "search.identify").
std::string_view IdentifyName(Identify identify);
// "topology or topology_and_stiffness": the accepted names, for messages and help.
std::string IdentifyNames();
// InputError(path, "unknown value 'x' (expected topology or topology_and_stiffness)").
Identify IdentifyFromName(const std::string& name, const std::string& path);

// How the training model responds (proto/SCENE.md, "search.response").
std::string_view ResponseName(Response response);
// InputError(path, "unknown value 'x' (expected linear or nonlinear)").
Response ResponseFromName(const std::string& name, const std::string& path);

// search.regularization: "auto", or a number >= 0 (as JSON, or as a command line's text).
SearchSettings::Regularization RegularizationFromText(const std::string& text,
                                                      const std::string& path);

// search.probes: "auto" (nullopt), "none" (0) or a count from 1 to SearchOptions::kMaxProbes,
// as a command line's text (JSON gives the count as a number). InputError(path, ...) otherwise.
std::optional<int> ProbesFromText(const std::string& text, const std::string& path);
// The JSON of search.probes: "none" for 0, else the count.
Json ProbesToJson(int probes);

// "default, paper, direct, hybrid or continuous": the accepted names, for messages.
std::string StrategyNames();
std::vector<Strategy> AllStrategies();

}  // namespace springfit::proto
