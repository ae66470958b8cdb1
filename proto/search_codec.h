// JSON and CSV forms of an identification's result and trace (`springfit run`, proto/RUN.md); the
// daemon's job.result and job.trace use the same forms.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "engine/api/identify.h"
#include "engine/api/problem.h"
#include "engine/api/result.h"
#include "proto/json_reader.h"

namespace springfit::proto {

// Every option, in a fixed order (the checkpoint's fingerprint of the resolved options hashes
// its text, server/jobs/checkpoint_codec.h).
Json SearchOptionsToJson(const SearchOptions& options);
// The options as the strategy that ran reads them (a result's `options`, proto/RUN.md): every
// strategy's time limit, spring budget, error target and load range (the verdict reads them),
// `target_normalized_error` for paper, hybrid and direct, the genetic search's for paper and
// hybrid, the fit's for continuous. On the probe fit (`fitted_to_probes`) a regularisation of 0
// is the continuation's choice, written "continuation", beside
// `generalization.fit.regularization`, the strength it chose.
Json RunOptionsToJson(const SearchOptions& options, Strategy ran, bool fitted_to_probes);
Json TraceRowToJson(const TraceRow& row);
// A missing or extra count, -1 (unknown: no reference topology) as null.
Json CountOrNull(int count);
// Reads what TraceRowToJson wrote; throws InputError naming the path.
TraceRow TraceRowFromJson(const Json& json, const std::string& path);
// A job.phase notification's fields (proto/RPC.md): where a step has got between two rows.
// `best_normalized_error` NaN (JSON null): no model yet in this phase.
Json ProgressBeatToJson(const ProgressBeat& beat);
struct PhaseBeat {
  std::string phase;
  ProgressBeat beat;  // its `phase` views the member above (valid while this object lives)
  PhaseBeat() = default;
  PhaseBeat(const PhaseBeat&) = delete;
  PhaseBeat& operator=(const PhaseBeat&) = delete;
};
// Reads what ProgressBeatToJson wrote into `out`; throws InputError naming the path.
void ProgressBeatFromJson(const Json& json, const std::string& path, PhaseBeat& out);
// The identifiability report (proto/RUN.md, "identifiability").
Json IdentifiabilityToJson(const IdentifiabilityReport& report);
// The result object of every strategy (proto/RUN.md): `stiffness` per spring of `springs`,
// strategy direct's `confidence` and `direct` details when it ran; the trace only when
// `with_trace`.
Json ResultToJson(const Problem& problem, const IdentificationResult& result, bool with_trace);

// A result object read back (a file from `run -o` / `result -o`, or job.result): the parts a
// figure draws, typed. The other fields are for people and other tools. Read only through
// StoredResultFromJson, which orders its node pairs: its readers look them up as they are.
struct StoredResult {
  std::string scene;  // the scene's name
  std::string strategy;
  std::optional<std::uint64_t> seed;
  std::optional<int> genes;
  std::string stop;                            // StopReasonName()
  std::vector<NodePair> springs;               // each (smaller, larger)
  std::vector<double> stiffness;               // per spring; empty when absent
  std::optional<std::vector<TraceRow>> trace;  // results written with their trace only
  // Strategy continuous: the sparsity path (springs, E) and the point returned from; the
  // closed-form baseline's E of an FEM reference.
  struct PathPoint {
    int springs = 0;
    double rms_error = 0.0;
  };
  std::vector<PathPoint> path;
  std::optional<int> chosen;
  std::optional<double> baseline_rms_error;
  std::optional<int> baseline_springs;
  std::optional<double> rms_error;  // E against the reference, where it has an equilibrium
  // Candidates no load case can see (never genes), and pairs whose stiffness the load cases
  // do not determine: `identifiability.unseen` and the springs of its groups.
  std::vector<NodePair> unidentifiable;
  std::vector<NodePair> undetermined;
  // False when the scene's dependent groups were not analysed (`identifiability.analysed`):
  // `undetermined` then holds the unseen springs alone, and whether the others are determined
  // is not known; `groups_not_analysed` says why (`identifiability.not_analysed`; empty in
  // results written before it was kept).
  bool groups_analysed = true;
  std::string groups_not_analysed;
  // The verdict and its headline numbers (`outcome`: results written since it exists), and the
  // certificate's generalised eigenvalues (`generalization.lambda_min`, `lambda_max`), for an
  // export to say what the result says.
  std::optional<Outcome> outcome;
  std::optional<double> lambda_min, lambda_max;
};
// Every node pair read (springs, unseen, groups, unidentifiable) is ordered (smaller, larger).
// Throws InputError naming the JSON path of the first problem.
StoredResult StoredResultFromJson(const Json& json);
// Throws InputError when `result` is detectably not a result of `problem`'s scene (another
// scene's name or gene count): its springs could still name valid node pairs.
void ExpectResultOfScene(const StoredResult& result, const Problem& problem);

// What a result's nonlinear fit left out and did not find (generalization.fit.nonlinear, as
// ResultToJson wrote it), in the words the run and the dashboard both show: "" when nothing,
// else each note after "; ".
std::string NonlinearFitNotes(const Json& nonlinear);

// One CSV line per trace row under a header line (no trailing newline in either).
std::string TraceCsvHeader();
std::string TraceRowToCsv(const TraceRow& row);

}  // namespace springfit::proto
