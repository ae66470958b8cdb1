// The daemon's job queue and the threads that run it.
//
// Queued jobs wait in priority order (higher first, then by id, i.e. submission order).
// Up to `max_running` jobs run at once, each on its own runner thread; all of them share
// one WorkerPool for their fitness evaluations, so a job running alone uses every worker,
// and several jobs share them generation by generation. Cancellation and shutdown are
// flags a job reads after each generation.
#pragma once
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <thread>
#include <utility>
#include <vector>

#include "engine/search/worker_pool.h"
#include "proto/json_reader.h"
#include "server/job_runner.h"
#include "server/job_store.h"

namespace springfit::server {

struct SchedulerOptions {
  int workers = 1;      // evaluation threads in total (the runner threads take part)
  int max_running = 1;  // jobs run at once
  JobRunnerOptions runner;
  double progress_seconds = 0.25;  // job.progress notifications per job at most this often
  // Queued jobs whose prepared problem (built when they were submitted) is kept for their run,
  // so that a job is prepared once; the others (beyond it, after a restart, or queued by
  // another daemon) are prepared again from their stored scene when they start.
  int max_prepared = 8;
};

class Scheduler {
 public:
  // A watcher receives job.progress and job.finished notifications (JSON-RPC objects). It
  // is called on a job's thread and must not block (a network session posts and returns).
  using Listener = std::function<void(const proto::Json& notification)>;

  Scheduler(JobStore& store, SchedulerOptions options);
  ~Scheduler();
  Scheduler(const Scheduler&) = delete;
  Scheduler& operator=(const Scheduler&) = delete;

  // Queues the store's unfinished jobs (interrupted ones resume) and starts the runners.
  void Start();
  // Queues a job the store has just created, with its prepared problem when the caller has it.
  void Enqueue(const JobRecord& job, std::shared_ptr<const Problem> prepared = nullptr);

  enum class CancelOutcome { kCancelled, kCancelling, kNotActive };
  // A queued job is cancelled at once; a running one after its current generation.
  CancelOutcome Cancel(std::int64_t id);

  // The latest generation of a running job (fresher than the store's, which is flushed).
  std::optional<TraceRow> LiveProgress(std::int64_t id) const;
  bool IsActive(std::int64_t id) const;  // queued or running here

  std::uint64_t Watch(std::int64_t id, Listener listener);
  void Unwatch(std::uint64_t token);

  // Stops starting jobs and asks running ones to checkpoint and stop after their current
  // generation. Returns true when every runner has stopped within `timeout`; the jobs that
  // have not are left to resume from their last checkpoint, as after a crash.
  bool Stop(std::chrono::milliseconds timeout);

  int running() const;
  int queued() const;

 private:
  struct Running {
    std::atomic<bool> cancel{false};
    std::optional<TraceRow> progress;  // guarded by mutex_
    std::chrono::steady_clock::time_point last_notified{};
  };

  void RunnerLoop();
  void Publish(std::int64_t id, const proto::Json& notification);
  void OnGeneration(std::int64_t id, Running& running, const JobRecord& job, const TraceRow& row);

  JobStore& store_;
  SchedulerOptions options_;
  WorkerPool pool_;

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::set<std::pair<int, std::int64_t>> queue_;  // (-priority, id)
  std::map<std::int64_t, int> queued_priority_;
  std::map<std::int64_t, std::shared_ptr<const Problem>> prepared_;  // of queued jobs
  std::map<std::int64_t, std::unique_ptr<Running>> running_;
  std::atomic<bool> stopping_{false};
  int runners_alive_ = 0;
  std::condition_variable runners_done_;
  std::vector<std::thread> runners_;

  std::mutex watch_mutex_;
  std::uint64_t next_token_ = 1;
  std::multimap<std::int64_t, std::pair<std::uint64_t, Listener>> watchers_;
};

}  // namespace springfit::server
