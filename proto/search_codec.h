// JSON and CSV forms of an identification's result and trace (`springfit run`, proto/RUN.md); the
// daemon's job.result and job.trace use the same forms.
#pragma once

#include <string>

#include "engine/identification/identification_result.h"
#include "engine/problem.h"
#include "proto/json_reader.h"

namespace springfit::proto {

Json SearchOptionsToJson(const SearchOptions& options);
Json TraceRowToJson(const TraceRow& row);
// A missing or extra count, -1 (unknown: no reference topology) as null.
Json CountOrNull(int count);
// Reads what TraceRowToJson wrote; throws InputError naming the path.
TraceRow TraceRowFromJson(const Json& json, const std::string& path);
// The identifiability report (proto/RUN.md, "identifiability").
Json IdentifiabilityToJson(const IdentifiabilityReport& report);
// The result object of every strategy (proto/RUN.md): `stiffness` per spring of `springs`,
// strategy direct's `confidence` and `direct` details when it ran; the trace only when
// `with_trace`.
Json ResultToJson(const Problem& problem, const IdentificationResult& result, bool with_trace);

// One CSV line per trace row under a header line (no trailing newline in either).
std::string TraceCsvHeader();
std::string TraceRowToCsv(const TraceRow& row);

}  // namespace springfit::proto
