// The daemon's runners: the threads that claim jobs from the store and run them.
//
// The queue is the store's (server/store/job_store.h): each runner claims the next job there (by
// priority, then submission order), so several daemons on one store share one queue. Up to
// `max_running` jobs run at once, each on its own runner thread; all of them share one
// WorkerPool for their fitness evaluations, so a job running alone uses every worker, and
// several jobs share them generation by generation.
//
// A monitor thread renews the leases of the jobs running here (the heartbeat) and learns from
// it of cancels requested through any daemon and of leases lost; it also follows the jobs
// watched here that run elsewhere (or wait in the queue), so that job.watch works whichever
// daemon the client is connected to.
#pragma once
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "engine/api/identify.h"
#include "proto/json_reader.h"
#include "server/jobs/job_runner.h"
#include "server/mutex.h"
#include "server/store/job_store.h"
#include "server/web/metrics.h"

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
  // This daemon's name in the leases it holds; unique among the daemons of one store. Empty:
  // host name, process id and a random suffix (DefaultOwnerName()).
  std::string owner;
  // A running job's lease lasts this long past its last heartbeat: how long the jobs of a
  // daemon that died wait before another daemon resumes them. A paused daemon loses its jobs
  // after it, and can then write nothing of them.
  double lease_seconds = 10.0;
  // Leases renewed, cancels requested elsewhere seen, and watched jobs of other daemons
  // followed this often. Below lease_seconds / 2, so one late beat loses nothing.
  double heartbeat_seconds = 1.0;
  // An idle runner looks for a job in the store this often when no wake-up came (a job
  // submitted here or announced by the store wakes it at once).
  double poll_seconds = 1.0;

  // Counts the fitness evaluations of the jobs run here, when set (/metrics).
  Metrics* metrics = nullptr;

  // Throws std::invalid_argument naming the option.
  void Validate() const;
};

// host:pid:random, for SchedulerOptions::owner.
std::string DefaultOwnerName();

class Scheduler {
 public:
  // A watcher receives job.progress and job.finished notifications (JSON-RPC objects). It
  // is called on a job's thread and must not block (a network session posts and returns).
  using Listener = std::function<void(const proto::Json& notification)>;

  Scheduler(JobStore& store, SchedulerOptions options);
  ~Scheduler();
  Scheduler(const Scheduler&) = delete;
  Scheduler& operator=(const Scheduler&) = delete;

  // Starts the runners and the monitor. Jobs left running by a dead daemon are claimed again
  // when their leases expire, and resume from their checkpoints.
  void Start();
  // The store has just created a job here: keeps its prepared problem for the run (when the
  // caller has it and this daemon claims the job) and wakes an idle runner.
  void JobSubmitted(std::int64_t id, std::shared_ptr<const Problem> prepared = nullptr);

  // A submission being prepared here (a job in state preparing, server/store/job_store.h): the
  // heartbeat renews its lease with the running jobs', and a cancel requested through any
  // daemon, or the lease lost, sets its flags; the preparation polls them. End it with
  // PreparationEnded, whatever the outcome.
  struct Preparation {
    std::atomic<bool> cancel{false};
    std::atomic<bool> lease_lost{false};
  };
  std::shared_ptr<const Preparation> PreparationStarted(const Lease& lease);
  // `job`: the job as its preparation left it (queued, or cancelled: watchers are told), or
  // nothing when it was to be dropped; `dropped`: it was (its watchers get job.gone; else the
  // monitor tells them once the row is swept).
  void PreparationEnded(std::int64_t id, const std::optional<JobRecord>& job, bool dropped);

  double lease_seconds() const { return options_.lease_seconds; }

  enum class CancelOutcome { kCancelled, kCancelling, kNotActive };
  // A queued job is cancelled at once; a running one (here or on another daemon) after its
  // current generation, or within a heartbeat and a second.
  CancelOutcome Cancel(std::int64_t id);

  // The latest generation of a job running here (fresher than the store's, which is flushed).
  std::optional<TraceRow> LiveProgress(std::int64_t id) const;
  // Where a job running here has got to inside its step (RunContext::on_beat): the phase, its
  // clock, and E so far (NaN: none yet). nullopt: not running here, or no beat yet.
  struct LivePhase {
    std::string phase;
    double wall_seconds = 0.0;
    double rms_error = 0.0;
    // The phase's time left at most (ProgressBeat::eta_seconds); NaN where it gives none.
    double eta_seconds = std::numeric_limits<double>::quiet_NaN();
  };
  std::optional<LivePhase> Phase(std::int64_t id) const;
  bool IsRunningHere(std::int64_t id) const;

  std::uint64_t Watch(std::int64_t id, Listener listener);
  void Unwatch(std::uint64_t token);

  // Stops starting jobs and asks running ones to checkpoint and stop after their current
  // generation. Returns true when every runner has stopped within `timeout`; the jobs that
  // have not are left to resume from their last checkpoint, as after a crash.
  bool Stop(std::chrono::milliseconds timeout);

  int running() const;  // here
  const std::string& owner() const { return options_.owner; }

 private:
  struct Running {
    Lease lease;
    std::atomic<bool> cancel{false};
    std::atomic<bool> lease_lost{false};
    // The job's thread writes them, readers of the scheduler read them (after mutex_, when
    // both are held).
    mutable Mutex live_mutex;
    std::optional<TraceRow> progress SF_GUARDED_BY(live_mutex);
    std::optional<LivePhase> phase SF_GUARDED_BY(live_mutex);
    std::chrono::steady_clock::time_point last_notified{};
    // The last job.phase sent (the job's thread).
    std::string last_phase;
    std::chrono::steady_clock::time_point last_phase_notified{};
    std::int64_t evaluations = 0;  // counted into the metrics so far (the job's thread)
  };

  void RunnerLoop();
  void RunClaimed(const Claim& claim);
  void MonitorLoop();
  void Heartbeat();
  void FollowWatched();
  // Wakes idle runners and the monitor (a job submitted here, or a change in the store).
  void Wake();
  void Publish(std::int64_t id, const proto::Json& notification);
  void PublishFinished(std::int64_t id, const JobRecord& job);
  // job.gone: a watched job that no longer exists (a submission dropped while prepared), or
  // whose row cannot be read (`why`).
  void PublishGone(std::int64_t id, const std::string& why = "");
  void OnGeneration(std::int64_t id, Running& running, const JobRecord& job, const TraceRow& row);
  void OnBeat(std::int64_t id, Running& running, const JobRecord& job, const ProgressBeat& beat);

  JobStore& store_;
  SchedulerOptions options_;
  WorkerPool pool_;

  mutable Mutex mutex_;
  std::condition_variable wake_;
  // Bumped by Wake(): a runner that saw it change looks again.
  std::uint64_t wake_count_ SF_GUARDED_BY(mutex_) = 0;
  // Of jobs submitted here.
  std::map<std::int64_t, std::shared_ptr<const Problem>> prepared_ SF_GUARDED_BY(mutex_);
  // At most one run per job: a claim of a job still running here waits on run_ended_.
  std::map<std::int64_t, std::unique_ptr<Running>> running_ SF_GUARDED_BY(mutex_);
  std::condition_variable run_ended_;
  std::map<std::int64_t, std::pair<Lease, std::shared_ptr<Preparation>>> preparing_
      SF_GUARDED_BY(mutex_);
  std::atomic<bool> stopping_{false};
  int runners_alive_ SF_GUARDED_BY(mutex_) = 0;
  std::condition_variable runners_done_;
  std::vector<std::thread> runners_;
  std::thread monitor_;

  Mutex watch_mutex_;
  std::uint64_t next_token_ SF_GUARDED_BY(watch_mutex_) = 1;
  std::multimap<std::int64_t, std::pair<std::uint64_t, Listener>> watchers_
      SF_GUARDED_BY(watch_mutex_);
  // Per watched job: the last generation announced (-1: none) and whether job.finished was.
  struct Announced {
    int generation = -1;
    bool finished = false;
  };
  std::map<std::int64_t, Announced> announced_ SF_GUARDED_BY(watch_mutex_);
};

}  // namespace springfit::server
