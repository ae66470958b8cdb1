#include "server/jobs/job_runner.h"

#include <chrono>
#include <limits>

#include <spdlog/spdlog.h>

#include "engine/identification/identify.h"
#include "proto/names.h"
#include "proto/outcome_codec.h"
#include "proto/scene_codec.h"
#include "proto/search_codec.h"
#include "server/jobs/checkpoint_codec.h"
#include "server/jobs/trace_policy.h"
#include "server/store/unix_time.h"

namespace springfit::server {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

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
  if (!result.outcome.reason.empty())
    spdlog::warn("job {}: no usable model: {}", record.id, result.outcome.reason);
  return record;
}

}  // namespace

JobRecord RunJob(JobStore& store, WorkerPool& pool, const Claim& claim,
                 std::shared_ptr<const Problem> prepared, const JobRunnerOptions& options,
                 const JobControl& control) {
  const JobRecord& job = claim.job;
  const Lease& lease = claim.lease;
  JobRecord record = job;
  // What the daemon asks of the job now: a cancel wins over a shutdown.
  struct Requests {
    bool cancel = false;
    bool shutdown = false;
  };
  const auto requests = [&control] {
    Requests r;
    const bool lost = control.lease_lost && control.lease_lost->load();
    r.cancel = !lost && control.cancel && control.cancel->load();
    r.shutdown = lost || (!r.cancel && control.shutdown && control.shutdown->load());
    return r;
  };
  try {
    if (!prepared) {
      const std::optional<std::string> scene = store.GetScene(job.id);
      if (!scene) throw std::runtime_error("the job's scene is missing from the store");
      // A large scene takes a while to prepare (its reference's Newton iterations): a cancel or
      // a shutdown stops the preparation between two of them.
      const auto stop_requested = [&] {
        const Requests r = requests();
        return r.cancel || r.shutdown;
      };
      Interruption stop(stop_requested, 0.1);
      if (stop_requested()) stop.Request();  // (asked before the first poll is due)
      try {
        prepared = std::make_shared<const Problem>(proto::SceneFromText(*scene),
                                                   EquilibriumOptions{}, &stop);
      } catch (const Interrupted&) {
        if (!requests().cancel) {
          const bool lost = control.lease_lost && control.lease_lost->load();
          spdlog::info(
              "job {} interrupted while being prepared ({}); it starts again {}", job.id,
              lost ? "its lease was lost" : "by the shutdown",
              lost ? "on the daemon that took it over" : "at the next start or on another daemon");
          return record;
        }
        const double finished_at = UnixNow();
        store.MarkFinished(lease, {JobState::kCancelled, "", "", std::nullopt, finished_at, ""});
        record.state = JobState::kCancelled;
        record.finished_at = finished_at;
        spdlog::info("job {} cancelled while being prepared", job.id);
        return record;
      }
    }
    const Problem& problem = *prepared;
    const SearchOptions search_options =
        ResolveSearchOptions(problem.scene().search, problem.gene_count());
    const int genes = problem.gene_count();
    const std::uint64_t fingerprint = OptionsFingerprint(search_options);

    RunContext run;
    run.pool = &pool;
    int resumed_at = -1;
    if (const std::optional<std::string> bytes = store.GetCheckpoint(job.id)) {
      try {
        run.resume_from = DecodeCheckpoint(*bytes, genes, fingerprint);
        resumed_at = run.resume_from->generation;
      } catch (const std::exception& e) {
        spdlog::warn("job {}: checkpoint unusable ({}); starting again from generation 0", job.id,
                     e.what());
      }
    }
    // Rows and improvements after the checkpoint are about to be produced again.
    store.RewindTo(lease, resumed_at);
    if (resumed_at >= 0) {
      spdlog::info("job {} running, resumed from its checkpoint at generation {}", job.id,
                   resumed_at);
    } else {
      spdlog::info("job {} running ({}, {} genes, strategy {}, seed {})", job.id, record.scene_name,
                   genes, record.strategy, record.seed);
    }

    ProgressBatch batch;
    auto last_flush = std::chrono::steady_clock::now();
    auto last_checkpoint = last_flush;
    double best_error = run.resume_from ? run.resume_from->best_fitness.normalized_error
                                        : std::numeric_limits<double>::infinity();
    bool interrupted = false;
    // Strategy direct reports once, finished, with nothing to checkpoint; its single row and
    // improvement are stored like a GA's, so job.trace, job.improvements and job.watch behave
    // the same.
    run.on_iteration = [&](const TraceRow& row, const IterationState& state) {
      const bool improved = row.best_normalized_error < best_error;
      if (improved) {
        best_error = row.best_normalized_error;
        batch.improvements.push_back({row.generation, row.wall_seconds, row.best_cost,
                                      row.best_normalized_error, row.missing, row.extra,
                                      *state.best});
      }
      const bool finished = state.finished;
      const Requests asked = requests();
      const bool cancel = asked.cancel;
      const bool shutdown = !finished && asked.shutdown;
      // A cancelled job's last row is kept; a shut-down job's is not special: it will be
      // produced again, and kept or not by the same rule, when the job resumes.
      if (KeepTraceRow(row.generation, improved, finished || cancel)) batch.trace.push_back(row);
      batch.latest = row;
      if (control.on_generation) control.on_generation(row);
      if (state.snapshot &&
          (shutdown ||
           (!finished && !cancel && SecondsSince(last_checkpoint) >= options.checkpoint_seconds))) {
        batch.checkpoint = EncodeCheckpoint(state.snapshot(), genes, fingerprint);
        batch.checkpoint_generation = row.generation;
        record.checkpoint_generation = row.generation;
        last_checkpoint = std::chrono::steady_clock::now();
      }
      if (batch.checkpoint || finished || cancel ||
          SecondsSince(last_flush) >= options.flush_seconds) {
        store.SaveProgress(lease, batch);
        batch = ProgressBatch{};
        last_flush = std::chrono::steady_clock::now();
      }
      record.progress = row;
      interrupted = interrupted || shutdown;  // once asked, a shutdown stays the reason
      return !cancel && !shutdown;
    };
    // Inside any step (analysis, direct phase, a generation): cancel and shutdown take effect
    // within a second (a shutdown then resumes from the last checkpoint, at a generation's end).
    run.on_beat = [&](const ProgressBeat& beat) {
      if (control.on_beat) control.on_beat(beat);
      const Requests asked = requests();
      if (asked.shutdown) interrupted = true;
      return !asked.cancel && !asked.shutdown;
    };
    const IdentificationResult result = RunIdentification(problem, search_options, run);
    // A stop inside a step reports no iteration: what the last ones left unflushed is stored now.
    if (control.lease_lost && control.lease_lost->load()) throw LeaseLost("the heartbeat lost it");
    if (!batch.trace.empty() || !batch.improvements.empty() || batch.latest)
      store.SaveProgress(lease, batch);
    if (interrupted && result.stop == StopReason::kCancelled) {
      spdlog::info(
          "job {} interrupted by the shutdown at generation {}; it resumes from its last "
          "checkpoint at the next start or on another daemon",
          job.id, result.generations);
      return record;
    }
    return FinishJob(store, lease, record, {result, proto::ResultToJson(problem, result, false)});
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
      store.MarkFinished(lease,
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
