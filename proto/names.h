// Enum <-> string mappings of the formats, in one place.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "engine/equilibrium.h"
#include "engine/scene.h"

namespace springfit::proto {

std::string_view CandidateKindName(CandidateSpec::Kind kind);
std::optional<CandidateSpec::Kind> ParseCandidateKind(std::string_view name);

std::string_view ReferenceKindName(Reference::Kind kind);
std::optional<Reference::Kind> ParseReferenceKind(std::string_view name);

std::string_view TerminationName(Termination termination);

// Search strategies a scene may name (proto/SCENE.md, "search").
inline constexpr std::string_view kStrategies[] = {"default", "paper"};

}  // namespace springfit::proto
