// The human-readable summary of a search result, from its JSON form (proto/RUN.md): the
// same lines for `springfit run` and for `springfit result` of a daemon's job.
#pragma once
#include <ostream>

#include "proto/json_reader.h"

namespace springfit::cli {

void PrintResultSummary(const proto::Json& result, std::ostream& out);

}  // namespace springfit::cli
