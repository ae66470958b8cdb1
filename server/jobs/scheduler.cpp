#include "server/jobs/scheduler.h"

#include <unistd.h>

#include <cmath>
#include <random>
#include <stdexcept>

#include <spdlog/spdlog.h>

#include "proto/rpc.h"
#include "proto/search_codec.h"
#include "server/store/unix_time.h"

namespace springfit::server {
namespace {

std::chrono::milliseconds Millis(double seconds) {
  return std::chrono::milliseconds(static_cast<long long>(seconds * 1000.0));
}

// A store that fails keeps failing for a while: its error is logged when it changes or every
// ten seconds, not at every poll.
class ErrorLog {
 public:
  void Report(const std::string& what, const std::exception& e) {
    MutexLock lock(mutex_);
    const auto now = std::chrono::steady_clock::now();
    const std::string message = what + ": " + e.what();
    if (message == last_ && now - logged_at_ < std::chrono::seconds(10)) return;
    last_ = message;
    logged_at_ = now;
    spdlog::error("{}", message);
  }

 private:
  Mutex mutex_;
  std::string last_ SF_GUARDED_BY(mutex_);
  std::chrono::steady_clock::time_point logged_at_ SF_GUARDED_BY(mutex_){};
};
ErrorLog store_errors;

}  // namespace

void SchedulerOptions::Validate() const {
  auto positive = [](double v, const char* name) {
    if (!(v > 0.0) || v > 86400.0)
      throw std::invalid_argument(std::string(name) + " must be in (0, 86400] seconds");
  };
  if (workers < 1) throw std::invalid_argument("workers must be at least 1");
  if (max_running < 1) throw std::invalid_argument("max_running must be at least 1");
  positive(lease_seconds, "lease_seconds");
  positive(heartbeat_seconds, "heartbeat_seconds");
  positive(poll_seconds, "poll_seconds");
  if (heartbeat_seconds > lease_seconds / 2) {
    throw std::invalid_argument("heartbeat_seconds (" + std::to_string(heartbeat_seconds) +
                                ") must be at most half of lease_seconds (" +
                                std::to_string(lease_seconds) + ")");
  }
}

std::string DefaultOwnerName() {
  char host[256] = {};
  if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  std::random_device random;
  return fmt::format("{}:{}:{:08x}", host[0] ? host : "host", ::getpid(), random());
}

Scheduler::Scheduler(JobStore& store, SchedulerOptions options)
    : store_(store), options_(std::move(options)), pool_(std::max(1, options_.workers)) {
  if (options_.owner.empty()) options_.owner = DefaultOwnerName();
  options_.Validate();
}

Scheduler::~Scheduler() {
  // The store outlives the scheduler: its listening thread must not call into a scheduler
  // that is gone.
  store_.SetChangeListener(nullptr);
  if (!Stop(std::chrono::hours(24 * 365))) {
    for (std::thread& t : runners_) t.detach();
    if (monitor_.joinable()) monitor_.detach();
  }
}

void Scheduler::Start() {
  store_.SetChangeListener([this] { Wake(); });
  MutexLock lock(mutex_);
  const int n = std::max(1, options_.max_running);
  runners_alive_ = n;
  for (int i = 0; i < n; ++i) runners_.emplace_back([this] { RunnerLoop(); });
  monitor_ = std::thread([this] { MonitorLoop(); });
}

void Scheduler::Wake() {
  {
    MutexLock lock(mutex_);
    ++wake_count_;
  }
  wake_.notify_all();
}

void Scheduler::JobSubmitted(std::int64_t id, std::shared_ptr<const Problem> prepared) {
  if (prepared) {
    MutexLock lock(mutex_);
    // Oldest first out: a job submitted here long ago has most likely been claimed elsewhere.
    while (!prepared_.empty() && static_cast<int>(prepared_.size()) >= options_.max_prepared)
      prepared_.erase(prepared_.begin());
    if (options_.max_prepared > 0) prepared_[id] = std::move(prepared);
  }
  Wake();
}

std::shared_ptr<const Scheduler::Preparation> Scheduler::PreparationStarted(const Lease& lease) {
  auto preparation = std::make_shared<Preparation>();
  MutexLock lock(mutex_);
  preparing_[lease.job_id] = {lease, preparation};
  return preparation;
}

void Scheduler::PreparationEnded(std::int64_t id, const std::optional<JobRecord>& job,
                                 bool dropped) {
  {
    MutexLock lock(mutex_);
    preparing_.erase(id);
  }
  if (!job) {
    if (dropped) PublishGone(id);
  } else if (proto::IsFinal(job->state)) {
    PublishFinished(id, *job);
  }
}

Scheduler::CancelOutcome Scheduler::Cancel(std::int64_t id) {
  bool here = false;
  {
    // A job running (or being prepared) here stops at once; the request is written all the
    // same, so that it survives a crash of this daemon before the job ends.
    MutexLock lock(mutex_);
    if (const auto r = running_.find(id); r != running_.end()) {
      r->second->cancel.store(true);
      here = true;
    }
    if (const auto p = preparing_.find(id); p != preparing_.end()) {
      p->second.second->cancel.store(true);
      here = true;
    }
  }
  const JobStore::CancelOutcome outcome = store_.RequestCancel(id);
  // A job stopped here by the flag may have recorded its end before the request reached the
  // store: it was running when asked, and is being cancelled.
  if (outcome == JobStore::CancelOutcome::kNotActive)
    return here ? CancelOutcome::kCancelling : CancelOutcome::kNotActive;
  if (outcome == JobStore::CancelOutcome::kRequested) return CancelOutcome::kCancelling;
  {
    MutexLock lock(mutex_);
    prepared_.erase(id);
  }
  spdlog::info("job {} cancelled while queued", id);
  if (const auto job = store_.GetJob(id)) PublishFinished(id, *job);
  return CancelOutcome::kCancelled;
}

std::optional<TraceRow> Scheduler::LiveProgress(std::int64_t id) const {
  MutexLock lock(mutex_);
  const auto r = running_.find(id);
  if (r == running_.end()) return std::nullopt;
  MutexLock live(r->second->live_mutex);
  return r->second->progress;
}

std::optional<Scheduler::LivePhase> Scheduler::Phase(std::int64_t id) const {
  MutexLock lock(mutex_);
  const auto r = running_.find(id);
  if (r == running_.end()) return std::nullopt;
  MutexLock live(r->second->live_mutex);
  return r->second->phase;
}

bool Scheduler::IsRunningHere(std::int64_t id) const {
  MutexLock lock(mutex_);
  return running_.contains(id);
}

int Scheduler::running() const {
  MutexLock lock(mutex_);
  return static_cast<int>(running_.size());
}

std::uint64_t Scheduler::Watch(std::int64_t id, Listener listener) {
  MutexLock lock(watch_mutex_);
  const std::uint64_t token = next_token_++;
  watchers_.emplace(id, std::make_pair(token, std::move(listener)));
  announced_.try_emplace(id);
  return token;
}

void Scheduler::Unwatch(std::uint64_t token) {
  MutexLock lock(watch_mutex_);
  for (auto it = watchers_.begin(); it != watchers_.end(); ++it) {
    if (it->second.first == token) {
      const std::int64_t id = it->first;
      watchers_.erase(it);
      if (!watchers_.contains(id)) announced_.erase(id);
      return;
    }
  }
}

void Scheduler::Publish(std::int64_t id, const proto::Json& notification) {
  MutexLock lock(watch_mutex_);
  const auto [first, last] = watchers_.equal_range(id);
  if (first == last) return;
  Announced& announced = announced_[id];
  const proto::Json& method = notification.at("method");
  if (method == "job.finished" || method == "job.gone") {
    if (announced.finished) return;  // the runner and the monitor may both see the end
    announced.finished = true;
  } else if (method == "job.phase") {
    if (announced.finished) return;  // (no phase after the end)
  } else {
    // Each generation once, in order (a job resumed from a checkpoint repeats some).
    const int generation = notification.at("params").value("generation", -1);
    if (announced.finished || generation <= announced.generation) return;
    announced.generation = generation;
  }
  for (auto it = first; it != last; ++it) it->second.second(notification);
}

void Scheduler::PublishFinished(std::int64_t id, const JobRecord& job) {
  Publish(id, proto::rpc::Notification("job.finished", proto::JobToJson(job)));
}

void Scheduler::PublishGone(std::int64_t id, const std::string& why) {
  proto::Json params;
  params["job_id"] = id;
  params["message"] = why.empty() ? "job " + std::to_string(id) +
                                        " no longer exists (a submission refused or abandoned "
                                        "while it was prepared, which was never acknowledged, "
                                        "or a job deleted)"
                                  : why;
  Publish(id, proto::rpc::Notification("job.gone", params));
}

bool Scheduler::Stop(std::chrono::milliseconds timeout) {
  {
    // Under the mutex: a runner between its check and its wait would miss the wake-up.
    MutexLock lock(mutex_);
    stopping_.store(true);
  }
  wake_.notify_all();
  bool stopped = false;
  {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    MutexLock lock(mutex_);
    while (runners_alive_ != 0 && lock.WaitUntil(runners_done_, deadline)) {
    }
    stopped = runners_alive_ == 0;
  }
  if (stopped) {
    for (std::thread& t : runners_) {
      if (t.joinable()) t.join();
    }
    if (monitor_.joinable()) monitor_.join();
  }
  return stopped;
}

void Scheduler::OnGeneration(std::int64_t id, Running& running, const JobRecord& job,
                             const TraceRow& row) {
  {
    MutexLock lock(running.live_mutex);
    running.progress = row;
  }
  if (options_.metrics) {
    options_.metrics->AddEvaluations(static_cast<std::int64_t>(row.evaluations) -
                                     running.evaluations);
    running.evaluations = static_cast<std::int64_t>(row.evaluations);
  }
  const auto now = std::chrono::steady_clock::now();
  if (row.generation != 0 && std::chrono::duration<double>(now - running.last_notified).count() <
                                 options_.progress_seconds) {
    return;
  }
  running.last_notified = now;
  proto::Json params = proto::TraceRowToJson(row);
  params["job_id"] = id;
  params["max_generations"] = job.max_generations;
  Publish(id, proto::rpc::Notification("job.progress", params));
}

void Scheduler::OnBeat(std::int64_t id, Running& running, const JobRecord& job,
                       const ProgressBeat& beat) {
  {
    MutexLock lock(running.live_mutex);
    running.phase = LivePhase{std::string(beat.phase), beat.wall_seconds,
                              std::sqrt(beat.best_normalized_error), beat.eta_seconds};
  }
  // A watcher sees where the step has got (a fit's steps, the sparsity path, the
  // certificate): each phase's first beat, then at most every progress_seconds.
  const auto now = std::chrono::steady_clock::now();
  if (beat.phase == running.last_phase &&
      std::chrono::duration<double>(now - running.last_phase_notified).count() <
          options_.progress_seconds)
    return;
  running.last_phase = std::string(beat.phase);
  running.last_phase_notified = now;
  proto::Json params = proto::ProgressBeatToJson(beat);
  params["job_id"] = id;
  params["max_generations"] = job.max_generations;
  Publish(id, proto::rpc::Notification("job.phase", params));
}

void Scheduler::RunnerLoop() {
  int failures = 0;  // consecutive store failures: the wait before the next claim grows
  while (!stopping_.load()) {
    std::uint64_t seen = 0;
    {
      MutexLock lock(mutex_);
      seen = wake_count_;
    }
    std::optional<Claim> claim;
    try {
      claim = store_.ClaimNext(options_.owner, options_.lease_seconds);
      failures = 0;
    } catch (const std::exception& e) {
      // The store is down: claim nothing, and look again later, less often while it stays so.
      store_errors.Report("cannot claim jobs from the store", e);
      ++failures;
    }
    if (claim) {
      RunClaimed(*claim);
      continue;
    }
    const double wait = failures == 0
                            ? options_.poll_seconds
                            : std::min(5.0, 0.1 * static_cast<double>(1 << std::min(failures, 6)));
    const auto deadline = std::chrono::steady_clock::now() + Millis(wait);
    MutexLock lock(mutex_);
    while (!stopping_.load() && !(failures == 0 && wake_count_ != seen) &&
           lock.WaitUntil(wake_, deadline)) {
    }
  }
  MutexLock lock(mutex_);
  if (--runners_alive_ == 0) runners_done_.notify_all();
  wake_.notify_all();  // the monitor ends with the last runner
}

void Scheduler::RunClaimed(const Claim& claim) {
  const std::int64_t id = claim.job.id;
  Running* running = nullptr;
  std::shared_ptr<const Problem> prepared;
  {
    MutexLock lock(mutex_);
    // This daemon may claim a job it is still running: its lease lapsed while the daemon
    // stood still (a host suspend, SIGSTOP, a store stall longer than the lease) and the
    // store handed it out again, to us. The older run has lost its lease to this claim: it is
    // told so, and this one starts only once it has stopped (one run of a job per process;
    // the new run resumes from the last checkpoint, so the result is the same).
    if (const auto old = running_.find(id); old != running_.end()) {
      if (!old->second->lease_lost.exchange(true)) {
        spdlog::warn(
            "job {}: claimed again (lease epoch {}) while its run of epoch {} goes on "
            "here: that run stops first",
            id, claim.lease.epoch, old->second->lease.epoch);
      }
      while (running_.contains(id)) lock.Wait(run_ended_);
    }
    if (const auto p = prepared_.find(id); p != prepared_.end()) {
      prepared = std::move(p->second);
      prepared_.erase(p);
    }
    auto slot = std::make_unique<Running>();
    slot->lease = claim.lease;
    slot->cancel.store(claim.cancel_requested);
    // A resumed job's counters go on from its checkpoint: those were counted before.
    if (claim.job.progress)
      slot->evaluations = static_cast<std::int64_t>(claim.job.progress->evaluations);
    running = slot.get();
    running_[id] = std::move(slot);
  }
  // A cancel written between the claim and the registration above reached the store only:
  // one beat now sees it, so that it takes effect before the first generation.
  try {
    const LeaseStatus status = store_.RenewLease(claim.lease, options_.lease_seconds);
    if (status.cancel_requested) running->cancel.store(true);
    if (!status.held) running->lease_lost.store(true);
  } catch (const std::exception& e) {
    store_errors.Report("job " + std::to_string(id) + ": cannot renew its lease", e);
  }
  JobControl control;
  control.cancel = &running->cancel;
  control.shutdown = &stopping_;
  control.lease_lost = &running->lease_lost;
  control.on_generation = [&](const TraceRow& row) { OnGeneration(id, *running, claim.job, row); };
  control.on_beat = [&](const ProgressBeat& beat) { OnBeat(id, *running, claim.job, beat); };
  const JobRecord after =
      RunJob(store_, pool_, claim, std::move(prepared), options_.runner, control);
  if (proto::IsFinal(after.state)) {
    if (options_.metrics) options_.metrics->CountFinished(after.state, after.outcome);
    std::optional<JobRecord> final_record;
    try {
      final_record = store_.GetJob(id);
    } catch (const std::exception&) {
    }
    PublishFinished(id, final_record.value_or(after));
  } else if (stopping_.load() && !running->lease_lost.load()) {
    // Stopped by a shutdown: another daemon of the store may resume the job at once.
    try {
      store_.ReleaseLease(claim.lease);
    } catch (const std::exception& e) {
      store_errors.Report("job " + std::to_string(id) + ": cannot release its lease", e);
    }
  }
  MutexLock lock(mutex_);
  // (Only this run's slot: a claim of the same job waits for it to go, run_ended_.)
  if (const auto r = running_.find(id); r != running_.end() && r->second.get() == running) {
    running_.erase(r);
    run_ended_.notify_all();
  }
}

void Scheduler::MonitorLoop() {
  auto next_beat = std::chrono::steady_clock::now();
  while (true) {
    std::uint64_t seen = 0;
    {
      MutexLock lock(mutex_);
      if (runners_alive_ == 0) break;
      seen = wake_count_;
    }
    if (std::chrono::steady_clock::now() >= next_beat) {
      Heartbeat();
      next_beat = std::chrono::steady_clock::now() + Millis(options_.heartbeat_seconds);
    }
    FollowWatched();
    MutexLock lock(mutex_);
    while (runners_alive_ != 0 && wake_count_ == seen && lock.WaitUntil(wake_, next_beat)) {
    }
  }
}

void Scheduler::Heartbeat() {
  std::vector<Lease> leases;
  {
    MutexLock lock(mutex_);
    for (const auto& [id, running] : running_) leases.push_back(running->lease);
  }
  for (const Lease& lease : leases) {
    try {
      const LeaseStatus status = store_.RenewLease(lease, options_.lease_seconds);
      // The job's run may have ended since the snapshot, and the job been claimed again into
      // a new slot (whose address may be the old one's): the answer is for this claim only,
      // known by its epoch, which every claim of the job increments.
      MutexLock lock(mutex_);
      const auto r = running_.find(lease.job_id);
      if (r == running_.end() || r->second->lease.epoch != lease.epoch) continue;
      Running& running = *r->second;
      if (!status.held && !running.lease_lost.exchange(true)) {
        spdlog::warn("job {}: lease lost to another daemon; stopping it here", lease.job_id);
      }
      if (status.cancel_requested) running.cancel.store(true);
    } catch (const std::exception& e) {
      store_errors.Report("job " + std::to_string(lease.job_id) + ": cannot renew its lease", e);
    }
  }
  // Submissions being prepared here: their slots are shared with the preparing threads.
  std::vector<std::pair<Lease, std::shared_ptr<Preparation>>> preparing;
  {
    MutexLock lock(mutex_);
    for (const auto& [id, entry] : preparing_) preparing.push_back(entry);
  }
  for (const auto& [lease, preparation] : preparing) {
    try {
      const LeaseStatus status = store_.RenewLease(lease, options_.lease_seconds);
      if (!status.held) preparation->lease_lost.store(true);
      if (status.cancel_requested) preparation->cancel.store(true);
    } catch (const std::exception& e) {
      store_errors.Report("job " + std::to_string(lease.job_id) + ": cannot renew its lease", e);
    }
  }
}

void Scheduler::FollowWatched() {
  std::vector<std::int64_t> ids;
  {
    MutexLock lock(watch_mutex_);
    for (const auto& [id, announced] : announced_) {
      if (!announced.finished) ids.push_back(id);
    }
  }
  for (const std::int64_t id : ids) {
    if (IsRunningHere(id)) continue;  // its runner announces it
    std::optional<JobRecord> job;
    try {
      job = store_.GetJob(id);
    } catch (const StoreCorrupt& e) {
      // Its row cannot be read (quarantined: it never runs again). Its watch ends; the other
      // watched jobs are followed on.
      PublishGone(id, e.what());
      continue;
    } catch (const std::exception& e) {
      store_errors.Report("cannot follow watched jobs", e);
      return;
    }
    if (!job) {
      // Only a submission dropped while it was prepared (elsewhere) vanishes unfinished.
      PublishGone(id);
      continue;
    }
    if (proto::IsFinal(job->state)) {
      PublishFinished(id, *job);
    } else if (job->progress) {
      // Publish drops it unless it is newer than the last generation announced.
      proto::Json params = proto::TraceRowToJson(*job->progress);
      params["job_id"] = id;
      params["max_generations"] = job->max_generations;
      Publish(id, proto::rpc::Notification("job.progress", params));
    }
  }
}

}  // namespace springfit::server
