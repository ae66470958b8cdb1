// A job of the daemon as the store keeps it and the wire shows it (proto/RPC.md, "Job").
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "engine/api/result.h"
#include "proto/json_reader.h"

namespace springfit::proto {

// preparing -> queued -> running -> succeeded | failed | cancelled. A submission is
// `preparing` while the daemon it was sent to solves its reference and lays out its
// candidates (seconds for a large scene); the submission is answered when that ends, and a
// scene found invalid then leaves no job. A running job interrupted by a shutdown or a crash
// is running again (from its checkpoint) after the restart; a preparing one was never
// acknowledged and is dropped.
enum class JobState { kPreparing, kQueued, kRunning, kSucceeded, kFailed, kCancelled };

std::string_view JobStateName(JobState state);
std::optional<JobState> ParseJobState(std::string_view name);
// Every state, in the order above (listings, filters, metrics).
std::vector<JobState> AllJobStates();
inline bool IsFinal(JobState s) {
  return s != JobState::kPreparing && s != JobState::kQueued && s != JobState::kRunning;
}

struct JobRecord {
  std::int64_t id = 0;
  std::string label;
  int priority = 0;  // higher runs first; equal priorities in submission order
  std::uint64_t seed = 1;
  std::string idempotency_key;  // empty: none
  JobState state = JobState::kQueued;
  std::string error;  // why it failed
  std::string scene_name;
  int genes = 0;
  std::string strategy;
  int max_generations = 0;
  double created_at = 0.0;  // Unix time in seconds; 0 = not yet
  double started_at = 0.0;
  double finished_at = 0.0;
  std::optional<TraceRow> progress;  // the last generation stored (or seen, while running)
  int checkpoint_generation = -1;    // generation of the last checkpoint; -1 = none
  std::optional<bool> exact;         // when finished and the reference topology is known
  // A finished job's verdict and headline numbers (engine/api/verdict.h), the same
  // as its result's `outcome`; absent before it finishes, when it failed, or stopped before it
  // had a model.
  std::optional<Outcome> outcome;
};

// A job whose progress rows count the steps of a fit (strategy continuous; a job's strategy
// is the one that runs) rather than generations of a genetic search up to max_generations:
// the one test of it for run, list, watch and the dashboard.
bool ProgressCountsSteps(std::string_view strategy);
// E of a job as list and the dashboard show it: the returned model's once the job has a
// verdict, the best so far marked "~" while it runs, "-" without either (3 digits).
std::string JobErrorText(const JobRecord& job);

// A duration for people: "0:07", "12:34", "1:02:03" (minutes:seconds under an hour,
// hours:minutes:seconds from it); "-" for a negative or non-finite one. The CLI's progress
// line and the dashboard say a phase's time left in it.
std::string ClockText(double seconds);

Json JobToJson(const JobRecord& job);
JobRecord JobFromJson(const Json& json);  // the client's reading; throws InputError

}  // namespace springfit::proto
