#include "server/scheduler.h"

#include <spdlog/spdlog.h>

#include "proto/rpc.h"
#include "proto/search_codec.h"
#include "server/unix_time.h"

namespace springfit::server {

Scheduler::Scheduler(JobStore& store, SchedulerOptions options)
    : store_(store), options_(options), pool_(std::max(1, options.workers)) {}

Scheduler::~Scheduler() {
  if (!Stop(std::chrono::hours(24 * 365))) {
    for (std::thread& t : runners_) t.detach();
  }
}

void Scheduler::Start() {
  for (const JobRecord& job : store_.UnfinishedJobs()) Enqueue(job);
  std::lock_guard lock(mutex_);
  const int n = std::max(1, options_.max_running);
  runners_alive_ = n;
  for (int i = 0; i < n; ++i) runners_.emplace_back([this] { RunnerLoop(); });
}

void Scheduler::Enqueue(const JobRecord& job, std::shared_ptr<const Problem> prepared) {
  {
    std::lock_guard lock(mutex_);
    if (queued_priority_.contains(job.id) || running_.contains(job.id)) return;
    queue_.insert({-job.priority, job.id});
    queued_priority_[job.id] = job.priority;
    if (prepared && static_cast<int>(prepared_.size()) < options_.max_prepared)
      prepared_[job.id] = std::move(prepared);
  }
  wake_.notify_one();
}

Scheduler::CancelOutcome Scheduler::Cancel(std::int64_t id) {
  {
    std::lock_guard lock(mutex_);
    if (const auto r = running_.find(id); r != running_.end()) {
      r->second->cancel.store(true);
      return CancelOutcome::kCancelling;
    }
    const auto q = queued_priority_.find(id);
    if (q == queued_priority_.end()) return CancelOutcome::kNotActive;
    queue_.erase({-q->second, id});
    queued_priority_.erase(q);
    prepared_.erase(id);
  }
  store_.MarkFinished(id, JobState::kCancelled, "", "", std::nullopt, UnixNow());
  spdlog::info("job {} cancelled while queued", id);
  if (const auto job = store_.GetJob(id)) {
    Publish(id, proto::rpc::Notification("job.finished", proto::JobToJson(*job)));
  }
  return CancelOutcome::kCancelled;
}

std::optional<TraceRow> Scheduler::LiveProgress(std::int64_t id) const {
  std::lock_guard lock(mutex_);
  const auto r = running_.find(id);
  if (r == running_.end()) return std::nullopt;
  return r->second->progress;
}

bool Scheduler::IsActive(std::int64_t id) const {
  std::lock_guard lock(mutex_);
  return running_.contains(id) || queued_priority_.contains(id);
}

int Scheduler::running() const {
  std::lock_guard lock(mutex_);
  return static_cast<int>(running_.size());
}

int Scheduler::queued() const {
  std::lock_guard lock(mutex_);
  return static_cast<int>(queue_.size());
}

std::uint64_t Scheduler::Watch(std::int64_t id, Listener listener) {
  std::lock_guard lock(watch_mutex_);
  const std::uint64_t token = next_token_++;
  watchers_.emplace(id, std::make_pair(token, std::move(listener)));
  return token;
}

void Scheduler::Unwatch(std::uint64_t token) {
  std::lock_guard lock(watch_mutex_);
  for (auto it = watchers_.begin(); it != watchers_.end(); ++it) {
    if (it->second.first == token) {
      watchers_.erase(it);
      return;
    }
  }
}

void Scheduler::Publish(std::int64_t id, const proto::Json& notification) {
  std::lock_guard lock(watch_mutex_);
  const auto [first, last] = watchers_.equal_range(id);
  for (auto it = first; it != last; ++it) it->second.second(notification);
}

bool Scheduler::Stop(std::chrono::milliseconds timeout) {
  {
    // Under the mutex: a runner between its check and its wait would miss the wake-up.
    std::lock_guard lock(mutex_);
    stopping_.store(true);
  }
  wake_.notify_all();
  std::unique_lock lock(mutex_);
  const bool stopped =
      runners_done_.wait_for(lock, timeout, [this] { return runners_alive_ == 0; });
  lock.unlock();
  if (stopped) {
    for (std::thread& t : runners_) {
      if (t.joinable()) t.join();
    }
  }
  return stopped;
}

void Scheduler::OnGeneration(std::int64_t id, Running& running, const JobRecord& job,
                             const TraceRow& row) {
  {
    std::lock_guard lock(mutex_);
    running.progress = row;
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

void Scheduler::RunnerLoop() {
  while (true) {
    JobRecord job;
    Running* running = nullptr;
    std::shared_ptr<const Problem> prepared;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [this] { return stopping_.load() || !queue_.empty(); });
      if (stopping_.load()) break;
      const auto [neg_priority, id] = *queue_.begin();
      queue_.erase(queue_.begin());
      queued_priority_.erase(id);
      if (const auto p = prepared_.find(id); p != prepared_.end()) {
        prepared = std::move(p->second);
        prepared_.erase(p);
      }
      auto slot = std::make_unique<Running>();
      running = slot.get();
      running_[id] = std::move(slot);
      job.id = id;
    }
    std::optional<JobRecord> stored;
    try {
      stored = store_.GetJob(job.id);
    } catch (const std::exception& e) {
      // Failed rather than forgotten: a job left queued would hold its watchers forever.
      spdlog::error("job {} failed: cannot read it from the store: {}", job.id, e.what());
      try {
        store_.MarkFinished(job.id, JobState::kFailed,
                            std::string("cannot read the job: ") + e.what(), "", std::nullopt,
                            UnixNow());
        if (const auto failed = store_.GetJob(job.id)) {
          Publish(job.id, proto::rpc::Notification("job.finished", proto::JobToJson(*failed)));
        }
      } catch (const std::exception& e2) {
        spdlog::error("job {}: cannot record the failure: {}", job.id, e2.what());
      }
    }
    if (stored && !proto::IsFinal(stored->state)) {
      JobControl control;
      control.cancel = &running->cancel;
      control.shutdown = &stopping_;
      control.on_generation = [&](const TraceRow& row) {
        OnGeneration(job.id, *running, *stored, row);
      };
      const JobRecord after =
          RunJob(store_, pool_, *stored, std::move(prepared), options_.runner, control);
      if (proto::IsFinal(after.state)) {
        std::optional<JobRecord> final_record;
        try {
          final_record = store_.GetJob(job.id);
        } catch (const std::exception&) {
        }
        Publish(job.id, proto::rpc::Notification("job.finished",
                                                 proto::JobToJson(final_record.value_or(after))));
      }
    }
    std::lock_guard lock(mutex_);
    running_.erase(job.id);
  }
  std::lock_guard lock(mutex_);
  if (--runners_alive_ == 0) runners_done_.notify_all();
}

}  // namespace springfit::server
