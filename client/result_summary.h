// The human-readable summary of a search result, from its JSON form (proto/RUN.md): the
// same lines for `springfit run` and for `springfit result` of a daemon's job.
#pragma once
#include <ostream>
#include <string>

#include "proto/json_reader.h"

namespace springfit::cli {

void PrintResultSummary(const proto::Json& result, std::ostream& out);

// On standard output: one compact JSON object (`--json`), or the summary.
void PrintResult(const proto::Json& result, bool as_json);

// The result (with its trace, for -o) as an indented JSON file; throws when it cannot.
void WriteResultFile(const std::string& path, const proto::Json& result);

}  // namespace springfit::cli
