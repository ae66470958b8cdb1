// Where the daemon keeps jobs, their traces, best topologies and checkpoints. An interface,
// so that a shared PostgreSQL store can replace the embedded SQLite one (sqlite_store.h).
//
// Every method is safe to call from several threads. Writes that belong together (a batch
// of trace rows with the checkpoint that follows them) are one transaction: after a crash
// the store holds either all of them or none.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "engine/problem.h"
#include "proto/job.h"

namespace springfit::server {

using proto::JobRecord;
using proto::JobState;

// A job as submitted: its record (state queued, no progress) and its scene.
struct NewJob {
  JobRecord record;
  std::string scene_json;  // the scene as submitted, with the job's seed written in
};

// One improvement of a job's best topology.
struct Improvement {
  int generation = 0;
  double wall_seconds = 0.0;
  double cost = 0.0;
  double normalized_error = 0.0;
  int missing = -1;
  int extra = -1;
  Genome genome;
};

// What a running job hands to the store at each flush: everything since the last one.
struct ProgressBatch {
  std::vector<TraceRow> trace;  // rows to keep (the trace policy already applied)
  std::vector<Improvement> improvements;
  std::optional<TraceRow> latest;         // the newest generation, kept or not
  std::optional<std::string> checkpoint;  // server/checkpoint_codec.h; replaces the last one
  int checkpoint_generation = -1;
};

struct JobFilter {
  std::optional<JobState> state;
  std::optional<std::string> label;
  int limit = 100;
  std::int64_t after_id = 0;  // the cursor: jobs with a greater id
};

struct JobPage {
  std::vector<JobRecord> jobs;
  std::optional<std::int64_t> next_cursor;  // set when more jobs match
};

class JobStore {
 public:
  virtual ~JobStore() = default;

  // Inserts a queued job and returns it with its id and creation time. When a job with the
  // same non-empty idempotency key exists, returns that job instead and `created` = false.
  struct Created {
    JobRecord job;
    bool created = true;
  };
  virtual Created CreateJob(const NewJob& job) = 0;
  virtual std::optional<JobRecord> GetJob(std::int64_t id) = 0;
  virtual std::optional<std::string> GetScene(std::int64_t id) = 0;
  virtual JobPage ListJobs(const JobFilter& filter) = 0;
  // Queued and running jobs, by priority (highest first) then id: what a restart schedules.
  virtual std::vector<JobRecord> UnfinishedJobs() = 0;
  virtual int CountQueued() = 0;

  virtual void MarkRunning(std::int64_t id, double started_at) = 0;
  virtual void SaveProgress(std::int64_t id, const ProgressBatch& batch) = 0;
  // Final state, its error (failed) and result JSON (succeeded or cancelled; may be empty).
  virtual void MarkFinished(std::int64_t id, JobState state, const std::string& error,
                            const std::string& result_json, std::optional<bool> exact,
                            double finished_at) = 0;

  virtual std::optional<std::string> GetResult(std::int64_t id) = 0;
  // Trace rows with generation > after, oldest first, at most `limit`.
  virtual std::vector<TraceRow> GetTrace(std::int64_t id, int after, int limit) = 0;
  virtual std::vector<Improvement> GetImprovements(std::int64_t id) = 0;
  virtual std::optional<std::string> GetCheckpoint(std::int64_t id) = 0;
  // Before a job resumes from its checkpoint (or restarts, at -1): drops the trace rows and
  // improvements recorded after that generation, which the job is about to produce again.
  virtual void RewindTo(std::int64_t id, int generation) = 0;
  // Deletes a finished job and everything stored with it; false when there is no such job.
  virtual bool DeleteJob(std::int64_t id) = 0;
};

}  // namespace springfit::server
