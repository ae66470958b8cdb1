// JSON and CSV forms of a search's result and trace (`springfit run`, proto/RUN.md); the
// daemon's job.result and job.trace use the same forms.
#pragma once

#include <string>

#include "engine/problem.h"
#include "engine/direct/run_direct.h"
#include "engine/search/run_search.h"
#include "proto/json_reader.h"

namespace springfit::proto {

Json SearchOptionsToJson(const SearchOptions& options);
Json TraceRowToJson(const TraceRow& row);
// A missing or extra count, -1 (unknown: no reference topology) as null.
Json CountOrNull(int count);
// Reads what TraceRowToJson wrote; throws InputError naming the path.
TraceRow TraceRowFromJson(const Json& json, const std::string& path);
// The result object; the trace is included only when `with_trace`.
// The identifiability report (proto/RUN.md, "identifiability").
Json IdentifiabilityToJson(const IdentifiabilityReport& report);
Json SearchResultToJson(const Problem& problem, const SearchResult& result, bool with_trace);
// Strategy direct: the search result's fields plus `stiffness` (per spring of `springs`) and
// `direct` (proto/RUN.md).
Json DirectRunToJson(const Problem& problem, const DirectRun& run, bool with_trace);

// One CSV line per trace row under a header line (no trailing newline in either).
std::string TraceCsvHeader();
std::string TraceRowToCsv(const TraceRow& row);

}  // namespace springfit::proto
