// Runs one job of the daemon: builds its problem from the stored scene, resumes from its
// checkpoint when it has one, searches, and records trace, improvements, checkpoints and the
// result in the store as it goes.
#pragma once
#include <atomic>
#include <functional>
#include <memory>

#include "engine/api/identify.h"
#include "engine/api/problem.h"
#include "server/store/job_store.h"

namespace springfit::server {

struct JobRunnerOptions {
  double flush_seconds = 1.0;        // trace rows and progress reach the store at least this often
  double checkpoint_seconds = 10.0;  // a checkpoint at least this often (and at a shutdown)
  // The share of the machine's memory a job may hold (RunContext::memory_share): the half a
  // run has alone, split among the jobs run at once (set by the daemon from --jobs).
  double memory_share = 0.5;
};

struct JobControl {
  const std::atomic<bool>* cancel = nullptr;    // job.cancel: stop, keep the best so far
  const std::atomic<bool>* shutdown = nullptr;  // the daemon stops: checkpoint, stay running
  // The heartbeat found the lease taken over: stop at once and write nothing more.
  const std::atomic<bool>* lease_lost = nullptr;
  // Every generation, on the job's thread (throttling is the listener's business).
  std::function<void(const TraceRow&)> on_generation;
  // Inside a step, about once a second: its phase (analysis, direct, genetic; a continuous
  // run's fit, path, refit...), on the job's thread.
  std::function<void(const ProgressBeat&)> on_beat;
};

// The job's record after the run: finished (succeeded, failed, cancelled), or still running
// when it was interrupted: by a shutdown, by the loss of its lease, or by a store it could not
// write (it resumes from its last checkpoint, here or on another daemon, once its lease
// expires or is released). Every write is fenced by the claim's lease.
// `prepared`: the job's problem as its submission prepared it, or null to prepare it from the
// stored scene.
JobRecord RunJob(JobStore& store, WorkerPool& pool, const Claim& claim,
                 std::shared_ptr<const Problem> prepared, const JobRunnerOptions& options,
                 const JobControl& control);

}  // namespace springfit::server
