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

// What the springs between held nodes (`outcome.unseen_springs`, both nodes held in every load
// case) are and get, in the words `check`, `run` and the dashboard share: no load case sees
// them, and exports add them at the recipe's stiffness on an FEM reference (`fem`; the training
// stiffness where no mesh edge joins them), at the training stiffness otherwise
// (Problem::unidentifiable_stiffness).
std::string HeldSpringsText(bool fem);

}  // namespace springfit::proto
