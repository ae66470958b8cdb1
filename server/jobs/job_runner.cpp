#include "server/jobs/job_runner.h"

#include <chrono>
#include <limits>

#include <spdlog/spdlog.h>

#include "engine/api/identify.h"
#include "proto/names.h"
#include "proto/outcome_codec.h"
#include "proto/scene_codec.h"
#include "proto/search_codec.h"
#include "server/jobs/checkpoint_codec.h"
#include "server/jobs/trace_policy.h"
#include "server/store/unix_time.h"

namespace springfit::server {
namespace {

// A finished run: the result, and its JSON as job.result answers it.
struct FinishedRun {
  IdentificationResult result;
  proto::Json json;
};

JobRecord FinishJob(JobStore& store, const Lease& lease, JobRecord& record, FinishedRun finished) {
  const IdentificationResult& result = finished.result;
  finished.json["job_id"] = record.id;
  record.state =
      result.stop == StopReason::kCancelled ? JobState::kCancelled : JobState::kSucceeded;
  record.exact = result.exact();
  record.outcome = result.outcome;
  record.finished_at = UnixNow();
  store.MarkFinished(lease, {record.state, "", finished.json.dump(), record.exact,
                             record.finished_at, proto::OutcomeToJson(result.outcome).dump()});
  // The verdict in the same words as `springfit run` and `result` (verdict.h).
  spdlog::info("job {} {} ({}), {:.3f} s{}: {}", record.id, proto::JobStateName(record.state),
               proto::StrategyName(result.ran), result.wall_seconds,
               record.exact ? (*record.exact ? ", exact" : ", not exact") : "",
               result.outcome.Headline());
  for (const std::string& line : result.outcome.unmet) spdlog::warn("job {}: {}", record.id, line);
  for (const std::string& line : result.outcome.doubts) spdlog::warn("job {}: {}", record.id, line);
  if (!result.outcome.reason.empty())
    spdlog::warn("job {}: no usable model: {}", record.id, result.outcome.reason);
  return record;
}

// What the daemon asks of the job now: a cancel wins over a shutdown.
struct Requests {
  bool cancel = false;
  bool shutdown = false;
};

// One claim of a job, run to its end, a stop or a failure: RunJob's steps (prepare, load the
// checkpoint, record each iteration's progress, finish). Every write goes through the claim's
// lease.
class JobRun {
 public:
  JobRun(JobStore& store, WorkerPool& pool, const Claim& claim, const JobRunnerOptions& options,
         const JobControl& control)
      : store_(store),
        pool_(pool),
        job_(claim.job),
        lease_(claim.lease),
        options_(options),
        control_(control),
        record_(claim.job),
        started_(std::chrono::steady_clock::now()) {}

  JobRecord& record() { return record_; }

  // The job's problem from its stored scene. A large scene takes a while to prepare (its
  // reference's Newton iterations): a cancel or a shutdown stops the preparation between two
  // of them, and then the run ends here (nullptr).
  std::shared_ptr<const Problem> Prepare() {
    const std::optional<std::string> scene = store_.GetScene(job_.id);
    if (!scene) throw std::runtime_error("the job's scene is missing from the store");
    const auto stop_requested = [this] {
      const Requests r = Asked();
      return r.cancel || r.shutdown;
    };
    Interruption stop(stop_requested, 0.1);
    if (stop_requested()) stop.Request();  // (asked before the first poll is due)
    try {
      return std::make_shared<const Problem>(proto::SceneFromText(*scene), EquilibriumOptions{},
                                             &stop);
    } catch (const Interrupted&) {
      StoppedWhilePreparing();
      return nullptr;
    }
  }

  // Runs the identification on `problem` from the job's checkpoint, if any, and records how it
  // ended.
  JobRecord Run(const Problem& problem) {
    const SearchOptions search_options =
        ResolveSearchOptions(problem.scene().search, problem.gene_count());
    genes_ = problem.gene_count();
    fingerprint_ = OptionsFingerprint(search_options);
    RunContext run;
    run.started = started_;  // the job's time limit counts from its claim, preparation included
    run.pool = &pool_;
    run.memory_share = options_.memory_share;
    run.resume_from = LoadCheckpoint();
    best_error_ = run.resume_from ? run.resume_from->best_fitness.normalized_error
                                  : std::numeric_limits<double>::infinity();
    last_flush_ = last_checkpoint_ = std::chrono::steady_clock::now();
    // Strategy direct reports once, finished, with nothing to checkpoint; its single row and
    // improvement are stored like a GA's, so job.trace, job.improvements and job.watch behave
    // the same.
    run.on_iteration = [this](const TraceRow& row, const IterationState& state) {
      return RecordIteration(row, state);
    };
    // Inside any step (analysis, direct phase, a generation): cancel and shutdown take effect
    // within a second (a shutdown then resumes from the last checkpoint, at a generation's end).
    run.on_beat = [this](const ProgressBeat& beat) {
      if (control_.on_beat) control_.on_beat(beat);
      const Requests asked = Asked();
      if (asked.shutdown) interrupted_ = true;
      return !asked.cancel && !asked.shutdown;
    };
    const IdentificationResult result = RunIdentification(problem, search_options, run);
    return Finish(problem, result);
  }

 private:
  Requests Asked() const {
    Requests r;
    const bool lost = LeaseLostNow();
    r.cancel = !lost && control_.cancel && control_.cancel->load();
    r.shutdown = lost || (!r.cancel && control_.shutdown && control_.shutdown->load());
    return r;
  }
  bool LeaseLostNow() const { return control_.lease_lost && control_.lease_lost->load(); }

  // A preparation stopped: cancelled, or left to start again (a shutdown, a lost lease).
  void StoppedWhilePreparing() {
    if (!Asked().cancel) {
      const bool lost = LeaseLostNow();
      spdlog::info(
          "job {} interrupted while being prepared ({}); it starts again {}", job_.id,
          lost ? "its lease was lost" : "by the shutdown",
          lost ? "on the daemon that took it over" : "at the next start or on another daemon");
      return;
    }
    const double finished_at = UnixNow();
    store_.MarkFinished(lease_, {JobState::kCancelled, "", "", std::nullopt, finished_at, ""});
    record_.state = JobState::kCancelled;
    record_.finished_at = finished_at;
    spdlog::info("job {} cancelled while being prepared", job_.id);
  }

  // The job's checkpoint, when it has a usable one; the trace and improvements after it are
  // dropped from the store, about to be produced again.
  std::optional<SearchState> LoadCheckpoint() {
    std::optional<SearchState> resume_from;
    int resumed_at = -1;
    if (const std::optional<std::string> bytes = store_.GetCheckpoint(job_.id)) {
      try {
        resume_from = DecodeCheckpoint(*bytes, genes_, fingerprint_);
        resumed_at = resume_from->generation;
      } catch (const std::exception& e) {
        spdlog::warn("job {}: checkpoint unusable ({}); starting again from generation 0", job_.id,
                     e.what());
      }
    }
    store_.RewindTo(lease_, resumed_at);
    if (resumed_at >= 0) {
      spdlog::info("job {} running, resumed from its checkpoint at generation {}", job_.id,
                   resumed_at);
    } else {
      spdlog::info("job {} running ({}, {} genes, strategy {}, seed {})", job_.id,
                   record_.scene_name, genes_, record_.strategy, record_.seed);
    }
    return resume_from;
  }

  // One iteration's progress into the batch (the trace policy's rows, improvements, the
  // latest row, a checkpoint when due), flushed when due; false stops the run.
  bool RecordIteration(const TraceRow& row, const IterationState& state) {
    const bool improved = row.best_normalized_error < best_error_;
    if (improved) {
      best_error_ = row.best_normalized_error;
      batch_.improvements.push_back({row.generation, row.wall_seconds, row.best_cost,
                                     row.best_normalized_error, row.missing, row.extra,
                                     *state.best});
    }
    const bool finished = state.finished;
    const Requests asked = Asked();
    const bool cancel = asked.cancel;
    const bool shutdown = !finished && asked.shutdown;
    // A cancelled job's last row is kept; a shut-down job's is not special: it will be
    // produced again, and kept or not by the same rule, when the job resumes.
    if (KeepTraceRow(row.generation, improved, finished || cancel)) batch_.trace.push_back(row);
    batch_.latest = row;
    if (control_.on_generation) control_.on_generation(row);
    if (state.snapshot &&
        (shutdown ||
         (!finished && !cancel && SecondsSince(last_checkpoint_) >= options_.checkpoint_seconds))) {
      batch_.checkpoint = EncodeCheckpoint(state.snapshot(), genes_, fingerprint_);
      batch_.checkpoint_generation = row.generation;
      record_.checkpoint_generation = row.generation;
      last_checkpoint_ = std::chrono::steady_clock::now();
    }
    if (batch_.checkpoint || finished || cancel ||
        SecondsSince(last_flush_) >= options_.flush_seconds) {
      store_.SaveProgress(lease_, batch_);
      batch_ = ProgressBatch{};
      last_flush_ = std::chrono::steady_clock::now();
    }
    record_.progress = row;
    interrupted_ = interrupted_ || shutdown;  // once asked, a shutdown stays the reason
    return !cancel && !shutdown;
  }

  // What the run left unflushed is stored; then the job is finished, or left to resume when a
  // shutdown stopped it.
  JobRecord Finish(const Problem& problem, const IdentificationResult& result) {
    // A stop inside a step reports no iteration: what the last ones left is stored now.
    if (LeaseLostNow()) throw LeaseLost("the heartbeat lost it");
    if (!batch_.trace.empty() || !batch_.improvements.empty() || batch_.latest)
      store_.SaveProgress(lease_, batch_);
    if (interrupted_ && result.stop == StopReason::kCancelled) {
      spdlog::info(
          "job {} interrupted by the shutdown at generation {}; it resumes from its last "
          "checkpoint at the next start or on another daemon",
          job_.id, result.generations);
      return record_;
    }
    return FinishJob(store_, lease_, record_,
                     {result, proto::ResultToJson(problem, result, false)});
  }

  JobStore& store_;
  WorkerPool& pool_;
  const JobRecord& job_;
  const Lease& lease_;
  const JobRunnerOptions& options_;
  const JobControl& control_;
  JobRecord record_;
  const std::chrono::steady_clock::time_point started_;  // the claim: the time limit counts from it
  int genes_ = 0;
  std::uint64_t fingerprint_ = 0;
  ProgressBatch batch_;
  std::chrono::steady_clock::time_point last_flush_;
  std::chrono::steady_clock::time_point last_checkpoint_;
  double best_error_ = std::numeric_limits<double>::infinity();
  bool interrupted_ = false;
};

}  // namespace

JobRecord RunJob(JobStore& store, WorkerPool& pool, const Claim& claim,
                 std::shared_ptr<const Problem> prepared, const JobRunnerOptions& options,
                 const JobControl& control) {
  const JobRecord& job = claim.job;
  JobRun run(store, pool, claim, options, control);
  JobRecord& record = run.record();
  try {
    if (!prepared) prepared = run.Prepare();
    if (!prepared) return record;
    return run.Run(*prepared);
  } catch (const LeaseLost& e) {
    // Another daemon runs the job now (this one was paused or cut off past the lease): its
    // work is the job's; this run's is dropped, and nothing of it was written.
    spdlog::warn("job {}: lease lost ({}); stopped without writing", job.id, e.what());
    record.state = job.state;  // (a final state set before its write failed is not the job's)
    return record;
  } catch (const StoreUnavailable& e) {
    // Nothing more can be written now: the job keeps its last checkpoint and resumes from it
    // when its lease expires and the store answers again (here or on another daemon).
    spdlog::error("job {} interrupted: {}; it resumes from its last checkpoint", job.id, e.what());
    record.state = job.state;
    return record;
  } catch (const std::exception& e) {
    record.state = JobState::kFailed;
    record.error = e.what();
    record.finished_at = UnixNow();
    spdlog::error("job {} failed: {}", job.id, record.error);
    try {
      store.MarkFinished(claim.lease,
                         {record.state, record.error, "", std::nullopt, record.finished_at, ""});
    } catch (const std::exception& e2) {
      // Lease lost, or the store unavailable: the job stays running in the store and is
      // claimed again (where it fails again, and that failure is recorded).
      spdlog::error("job {}: cannot record the failure: {}", job.id, e2.what());
      record = job;
    }
  }
  return record;
}

}  // namespace springfit::server
