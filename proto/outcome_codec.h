// The verdict of a result (engine/api/verdict.h) on the wire: the `outcome` object
// of a result (proto/RUN.md, "Outcome") and of a finished job (proto/RPC.md, "Job").
#pragma once

#include <string>

#include "engine/api/result.h"
#include "proto/json_reader.h"

namespace springfit::proto {

Json OutcomeToJson(const Outcome& outcome);
// Reads what OutcomeToJson wrote; unknown keys are ignored (a newer daemon's). Throws
// InputError naming `path` and the field.
Outcome OutcomeFromJson(const Json& json, const std::string& path);

}  // namespace springfit::proto
