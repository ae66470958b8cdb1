// Where the daemons keep jobs, their traces, best topologies and checkpoints, and the queue
// they claim jobs from: the embedded SQLite store (sqlite_store.h, one daemon) or a shared
// PostgreSQL one (postgres_store.h, several daemons on one database).
//
// The store is the scheduler. A daemon claims the next job (highest priority, then oldest;
// or a running job whose lease has expired, its daemon being dead or cut off) in one
// statement, and holds it through a lease: an owner, an epoch that every claim increments,
// and an expiry the runner's heartbeat pushes back. Every write of a running job (progress,
// checkpoint, rewind, finish) is fenced by owner and epoch, so a daemon that lost its lease
// (paused, partitioned) can never overwrite the work of the one that took over: the write
// throws LeaseLost and changes nothing.
//
// Every method is safe to call from several threads. Writes that belong together (a batch
// of trace rows with the checkpoint that follows them) are one transaction: after a crash
// the store holds either all of them or none.
#pragma once
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "engine/api/problem.h"
#include "proto/job.h"

namespace springfit::server {

using proto::JobRecord;
using proto::JobState;

// A job as submitted: its record (no progress) and its scene.
struct NewJob {
  JobRecord record;
  std::string scene_json;  // the scene as submitted, with the job's seed written in
  // Set: the job is created `preparing`, held by this daemon through a lease (as a running
  // job is) while its submission is prepared here; FinishPreparing or DropPreparing ends
  // that. Empty: it is created queued.
  std::string preparing_owner;
  double lease_seconds = 10.0;
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
  std::optional<std::string> checkpoint;  // server/jobs/checkpoint_codec.h; replaces the last one
  int checkpoint_generation = -1;
};

// A running job's claim: who holds it, and which claim of the job this is.
struct Lease {
  std::int64_t job_id = 0;
  std::string owner;
  std::int64_t epoch = 0;
};

// A job claimed by a daemon: its record (state running), its lease, and whether a cancel
// was requested before the claim (an expired job claimed again).
struct Claim {
  JobRecord job;
  Lease lease;
  bool cancel_requested = false;
};

// How a job ended, as MarkFinished stores it.
struct JobEnd {
  JobState state = JobState::kSucceeded;
  std::string error;          // why it failed
  std::string result_json;    // succeeded or cancelled; may be empty
  std::optional<bool> exact;  // when the reference topology is known
  double finished_at = 0.0;
  std::string outcome_json;  // the result's verdict (proto/outcome_codec.h); empty: none
};

// What a heartbeat learns: whether the lease is still this daemon's, and whether a client
// asked (through any daemon) to cancel the job.
struct LeaseStatus {
  bool held = false;
  bool cancel_requested = false;
};

// One claim of a job as the store's lease history keeps it (every claim, in the store's clock,
// written in the transaction that changed the lease): who held the job, from when, and until
// when. Deleted with its job.
struct LeaseRecord {
  std::int64_t epoch = 0;
  std::string owner;
  double granted_at = 0.0;
  double expires_at = 0.0;  // the expiry its last renewal set
  // When the holder ended it (handed it back, finished, prepared it; or the store set it
  // aside); none while it is held, or when it lapsed (its holder died, froze or was cut off)
  // and was claimed again, which `expires_at` then bounds.
  std::optional<double> ended_at;
  std::string ended;  // how: kLeaseReleased ... below; empty with ended_at
};
inline constexpr const char* kLeaseReleased = "released";        // ReleaseLease
inline constexpr const char* kLeaseFinished = "finished";        // MarkFinished
inline constexpr const char* kLeasePrepared = "prepared";        // FinishPreparing
inline constexpr const char* kLeaseQuarantined = "quarantined";  // its row set aside
// SQLite: a daemon opening the store found the lease of one that is gone (the file's lock).
inline constexpr const char* kLeaseHolderGone = "holder gone";

// A job ran in one place at a time when each of its claims began after the one before it had
// ended or expired, and epochs rise with time: the first claim of `history` (epoch order) that
// breaks this, described ("claim 3 by b at 1700000012.5 while claim 2 by a held it until
// 1700000013.0"), or nothing.
std::optional<std::string> LeaseOverlap(const std::vector<LeaseRecord>& history);

// A fenced write found the job claimed by another daemon, finished or deleted: nothing written.
class LeaseLost : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The store cannot be reached or written now (connection lost, server restarting, disk full):
// nothing was written. A later call may succeed.
class StoreUnavailable : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Within its scope, this thread's calls to the store give up after `seconds` (a
// StoreUnavailable saying so) where the store bounds its calls (PostgreSQL: PostgresStore::
// Options::call_seconds, which a shorter deadline here overrides): for answers that must come
// at once whatever the store does, such as server.info's count of the queue.
class ScopedStoreDeadline {
 public:
  explicit ScopedStoreDeadline(double seconds);
  ~ScopedStoreDeadline();
  ScopedStoreDeadline(const ScopedStoreDeadline&) = delete;
  ScopedStoreDeadline& operator=(const ScopedStoreDeadline&) = delete;
  // The innermost deadline of this thread (seconds), or 0 for none.
  static double Current();

 private:
  double previous_;
};

// A job whose stored row could not be read (a value no springfitd writes) and was set aside
// by the store that found it: its state is `quarantined` in the database, so that no daemon
// claims or counts it, and its other columns stay as they were found, for an operator to
// repair or delete. Every other job goes on.
struct QuarantinedJob {
  std::int64_t job_id = 0;
  std::int64_t incident = 0;  // the store's number for it, one per job, shared by its daemons
  std::string reason;         // what could not be read (StoreCorrupt's message)
  double quarantined_at = 0.0;
  std::string previous_state;  // the row's state when quarantined: to set back once repaired
};

// A stored record cannot be read: the database holds a value no springfitd writes (an unknown
// state, a progress column that is not a trace row). Nothing else was changed; the other
// records stay readable. A job's row is quarantined by then (`incident` its number); the RPC
// answers kStoreCorrupt with that incident, or with one of its own (proto/RPC.md).
class StoreCorrupt : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
  explicit StoreCorrupt(const QuarantinedJob& quarantined);
  // The quarantine's incident number; 0 when the record was not quarantined.
  std::int64_t incident() const { return incident_; }

 private:
  std::int64_t incident_ = 0;
};

// The job state stored for `job_id`, or StoreCorrupt naming the value.
JobState StoredJobState(std::int64_t job_id, const std::string& text);
// The progress row stored for `job_id` (its JSON text), or StoreCorrupt naming what is wrong.
TraceRow StoredProgress(std::int64_t job_id, const std::string& text);
// The verdict stored for `job_id` (its JSON text), or StoreCorrupt naming what is wrong.
Outcome StoredOutcome(std::int64_t job_id, const std::string& text);

struct JobFilter {
  std::optional<JobState> state;
  std::optional<std::string> label;
  int limit = 100;
  // Oldest first from the cursor: jobs with a greater id. Newest first (the dashboard):
  // jobs with a smaller id, or from the newest when the cursor is 0.
  std::int64_t after_id = 0;
  bool newest_first = false;
};

struct JobPage {
  std::vector<JobRecord> jobs;
  // The page's jobs that are quarantined (found so now, or before), by id: `jobs` goes on
  // without them, and the page's limit and cursor count them.
  std::vector<QuarantinedJob> quarantined;
  std::optional<std::int64_t> next_cursor;  // set when more jobs match
};

class JobStore {
 public:
  virtual ~JobStore() = default;

  // Inserts a queued job (or a preparing one, NewJob::preparing_owner) and returns it with
  // its id and creation time. When a job with the same non-empty idempotency key exists,
  // returns that job instead and `created` = false. When `max_queued` jobs are queued or
  // preparing already (counted in the same transaction, so the bound holds across daemons),
  // inserts nothing and sets `queue_full`.
  struct Created {
    JobRecord job;
    bool created = true;
    bool queue_full = false;
    Lease lease;  // a preparing job's
  };
  virtual Created CreateJob(const NewJob& job, int max_queued) = 0;
  // A preparing job's submission is prepared: it becomes queued, with the genes, strategy and
  // generation limit its preparation found, or cancelled when a cancel was requested
  // meanwhile. Returns the new state. Throws LeaseLost when the lease is no longer held.
  virtual JobState FinishPreparing(const Lease& lease, const JobRecord& prepared) = 0;
  // A preparing job whose scene was found invalid, or whose submitter went away, was never
  // acknowledged: it is deleted (nothing happens when the lease is no longer held).
  // Preparing jobs whose lease expired (their daemon died) are deleted by the next claim.
  virtual void DropPreparing(const Lease& lease) = 0;
  virtual std::optional<JobRecord> GetJob(std::int64_t id) = 0;
  virtual std::optional<std::string> GetScene(std::int64_t id) = 0;
  virtual JobPage ListJobs(const JobFilter& filter) = 0;
  // Queued and running jobs, by priority (highest first) then id.
  virtual std::vector<JobRecord> UnfinishedJobs() = 0;
  virtual int CountQueued() = 0;
  // Jobs by state (the states with none are absent).
  virtual std::map<JobState, int> CountJobs() = 0;

  // The scheduler's side. ClaimNext takes the highest-priority queued job (then the oldest),
  // or a running one whose lease expired, for `owner` until `lease_seconds` from now (the
  // store's clock), or returns nothing. The job's started_at is set at its first claim.
  virtual std::optional<Claim> ClaimNext(const std::string& owner, double lease_seconds) = 0;
  // Extends the lease (of a running or a preparing job) when it is still held.
  virtual LeaseStatus RenewLease(const Lease& lease, double lease_seconds) = 0;
  // Lets another daemon claim the job at once (a daemon stopping with the job unfinished).
  virtual void ReleaseLease(const Lease& lease) = 0;

  // Fenced writes: each throws LeaseLost when `lease` is no longer the job's. MarkFinished
  // also ends a preparing job (cancelled while being prepared).
  virtual void SaveProgress(const Lease& lease, const ProgressBatch& batch) = 0;
  // The final state and what goes with it (JobEnd).
  virtual void MarkFinished(const Lease& lease, const JobEnd& end) = 0;
  // Before a job resumes from its checkpoint (or restarts, at -1): drops the trace rows and
  // improvements recorded after that generation, which the job is about to produce again.
  virtual void RewindTo(const Lease& lease, int generation) = 0;

  // job.cancel from any daemon: a queued job is cancelled at once (kCancelled); a running or
  // preparing one gets the request, which its daemon's heartbeat reads (kRequested); a
  // finished or missing one is left alone (kNotActive).
  enum class CancelOutcome { kCancelled, kRequested, kNotActive };
  virtual CancelOutcome RequestCancel(std::int64_t id) = 0;

  virtual std::optional<std::string> GetResult(std::int64_t id) = 0;
  // Trace rows with generation > after, oldest first, at most `limit`.
  virtual std::vector<TraceRow> GetTrace(std::int64_t id, int after, int limit) = 0;
  // Improvements with generation > page.after, oldest first, at most page.limit (0: all); with
  // page.last the newest one alone (what a figure of the best so far needs).
  struct ImprovementPage {
    int after = -1;
    int limit = 0;
    bool last = false;
  };
  virtual std::vector<Improvement> GetImprovements(std::int64_t id,
                                                   const ImprovementPage& page) = 0;
  std::vector<Improvement> GetImprovements(std::int64_t id) { return GetImprovements(id, {}); }
  virtual std::optional<std::string> GetCheckpoint(std::int64_t id) = 0;
  // Every claim of the job (its lease history), oldest first; empty for no such job.
  virtual std::vector<LeaseRecord> LeaseHistory(std::int64_t id) = 0;
  // Deletes a finished job and everything stored with it; false when there is no such job
  // or it is not finished.
  virtual bool DeleteJob(std::int64_t id) = 0;

  // Called (on a thread of the store) when another daemon changed the queue or a job: a
  // wake-up for the scheduler, which then reads the store. Stores of one daemon never call
  // it. Set before the scheduler starts.
  virtual void SetChangeListener(std::function<void()> listener) { (void)listener; }
  // A short description for logs, without secrets ("sqlite:///var/lib/springfit.db").
  virtual std::string Describe() const = 0;
};

}  // namespace springfit::server
