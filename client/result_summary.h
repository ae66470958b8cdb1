// The human-readable summary of a search result, from its JSON form (proto/RUN.md): the
// same lines for `springfit run` and for `springfit result` of a daemon's job.
#pragma once
#include <ostream>
#include <string>

#include "engine/api/result.h"
#include "proto/json_reader.h"

namespace springfit::cli {

void PrintResultSummary(const proto::Json& result, std::ostream& out);
// The verdict (engine/api/verdict.h): the one line a pipeline reads, then a WARNING
// line per unmet request, or why there is no usable model. The same words for a result and a
// job (`status`, `watch`).
void PrintOutcome(const Outcome& outcome, std::ostream& out);

// On standard output: one compact JSON object (`--json`), or the summary.
void PrintResult(const proto::Json& result, bool as_json);

// The result file of `-o` (proto/RUN.md): the result with its trace, and the scene it was
// found on as `scene_definition`, so that `springfit render FILE` needs nothing else.
// Indented JSON; throws when it cannot be written.
void WriteResultFile(const std::string& path, const proto::Json& result, const proto::Json& scene);

}  // namespace springfit::cli
