// Deciding a result's verdict (engine/api/verdict.h says what the verdict is and what the
// surfaces show of it): the one judge, at the end of RunIdentification.
#pragma once

#include "engine/api/problem.h"
#include "engine/api/result.h"
#include "engine/api/verdict.h"

namespace springfit {

// Judges `result` (of `problem`).
Outcome JudgeResult(const Problem& problem, const IdentificationResult& result);

}  // namespace springfit
