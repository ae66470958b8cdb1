// What the scheduler's tests (scheduler_test.cpp, scheduler_cancel_test.cpp) share: an
// endless scene, the SQLite store with test hooks, the notifications of watched jobs, waits
// bounded in time, and the fixture.
#pragma once
#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <future>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "proto/json_reader.h"
#include "proto/scene_codec.h"
#include "server/jobs/scheduler.h"
#include "server/store/forwarding_store.h"
#include "server/store/sqlite_store.h"
#include "tests/test_scenes.h"

namespace springfit::server {

inline constexpr std::chrono::seconds kBound{60};

// A small scene whose search cannot end by itself within a test: its training springs are
// half as stiff as the reference's, so no topology reproduces the reference (the target is
// never reached), nothing stops it for stalling, and its generation budget is out of reach.
// Only a cancel ends it. max_seconds bounds the damage of a lost cancel: such a job ends
// "succeeded" (time limit) after 20 s, which the tests report, instead of running forever.
inline Scene EndlessScene() {
  Scene s = springfit::testing::GridScene(2, 3);
  s.training_stiffness = 0.5;
  s.search.strategy = Strategy::kPaper;
  s.search.max_generations = 1000000;
  s.search.stall_generations = 0;
  s.search.max_seconds = 20.0;
  return s;
}

// The SQLite store with test hooks: one right after an armed job is claimed (before its
// runner registers it), a count of scene reads, and a record of every way a job ended
// (MarkFinished, or a cancel that took it off the queue).
class HookedStore final : public ForwardingStore {
 public:
  using ForwardingStore::ForwardingStore;

  // Called with the job's id; set before Scheduler::Start().
  std::function<void(std::int64_t)> on_claim;
  void Arm(std::int64_t id) {
    std::lock_guard lock(mutex_);
    armed_.insert(id);
  }
  std::vector<JobState> Finishes(std::int64_t id) {
    std::lock_guard lock(mutex_);
    const auto it = finishes_.find(id);
    return it == finishes_.end() ? std::vector<JobState>{} : it->second;
  }
  std::vector<std::int64_t> Claimed() {
    std::lock_guard lock(mutex_);
    return claimed_;
  }
  long ClaimsOf(std::int64_t id) {
    std::lock_guard lock(mutex_);
    return std::count(claimed_.begin(), claimed_.end(), id);
  }

  // From now on no claim reaches the store once `claims` were made (a daemon alone with its
  // job, whose lapsed lease nobody takes): what a test then sees does not depend on whether a
  // loaded machine let a lease lapse.
  void LimitClaims(long claims) {
    std::lock_guard lock(mutex_);
    max_claims_ = claims;
  }
  std::optional<Claim> ClaimNext(const std::string& owner, double lease_seconds) override {
    {
      std::lock_guard lock(mutex_);
      if (max_claims_ >= 0 && static_cast<long>(claimed_.size()) >= max_claims_)
        return std::nullopt;
    }
    std::optional<Claim> claim = inner_.ClaimNext(owner, lease_seconds);
    if (!claim) return claim;
    bool fire = false;
    {
      std::lock_guard lock(mutex_);
      claimed_.push_back(claim->job.id);
      fire = armed_.erase(claim->job.id) > 0;
    }
    if (fire && on_claim) on_claim(claim->job.id);
    return claim;
  }
  std::optional<std::string> GetScene(std::int64_t id) override {
    {
      std::lock_guard lock(mutex_);
      ++scene_reads_[id];
    }
    return inner_.GetScene(id);
  }
  int SceneReads(std::int64_t id) {
    std::lock_guard lock(mutex_);
    return scene_reads_[id];
  }
  void MarkFinished(const Lease& lease, const JobEnd& end) override {
    inner_.MarkFinished(lease, end);
    std::lock_guard lock(mutex_);
    finishes_[lease.job_id].push_back(end.state);
  }
  // The next lease renewal stalls before it reaches the store (a stalled database) until
  // `until` holds (30 s at most).
  void StallNextRenewal(std::function<bool()> until) {
    std::lock_guard lock(mutex_);
    stall_until_ = std::move(until);
  }
  LeaseStatus RenewLease(const Lease& lease, double lease_seconds) override {
    std::function<bool()> until;
    {
      std::lock_guard lock(mutex_);
      std::swap(until, stall_until_);
    }
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (until && !until() && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    return inner_.RenewLease(lease, lease_seconds);
  }
  // Every progress write attempted, in order: (job, lease epoch).
  void SaveProgress(const Lease& lease, const ProgressBatch& batch) override {
    {
      std::lock_guard lock(mutex_);
      progress_writes_.emplace_back(lease.job_id, lease.epoch);
    }
    inner_.SaveProgress(lease, batch);
  }
  std::vector<std::int64_t> ProgressEpochs(std::int64_t id) {
    std::lock_guard lock(mutex_);
    std::vector<std::int64_t> epochs;
    for (const auto& [job, epoch] : progress_writes_)
      if (job == id) epochs.push_back(epoch);
    return epochs;
  }
  CancelOutcome RequestCancel(std::int64_t id) override {
    const CancelOutcome outcome = inner_.RequestCancel(id);
    if (outcome == CancelOutcome::kCancelled) {
      std::lock_guard lock(mutex_);
      finishes_[id].push_back(JobState::kCancelled);
    }
    return outcome;
  }

 private:
  std::function<bool()> stall_until_;
  long max_claims_ = -1;  // no limit
  std::vector<std::pair<std::int64_t, std::int64_t>> progress_writes_;
  std::map<std::int64_t, int> scene_reads_;
  std::mutex mutex_;
  std::set<std::int64_t> armed_;
  std::vector<std::int64_t> claimed_;
  std::map<std::int64_t, std::vector<JobState>> finishes_;
};

// The notifications of watched jobs, from any thread.
class Notifications {
 public:
  Scheduler::Listener For(std::int64_t id) {
    return [this, id](const proto::Json& n) {
      std::lock_guard lock(mutex_);
      by_job_[id].push_back(n);
      changed_.notify_all();
    };
  }
  // Waits at most kBound for a job.finished of every job of `ids`.
  bool WaitFinished(const std::vector<std::int64_t>& ids) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, kBound, [&] {
      return std::all_of(ids.begin(), ids.end(),
                         [&](std::int64_t id) { return !OfLocked(id, "job.finished").empty(); });
    });
  }
  std::vector<proto::Json> Of(std::int64_t id, const std::string& method) {
    std::lock_guard lock(mutex_);
    return OfLocked(id, method);
  }

 private:
  std::vector<proto::Json> OfLocked(std::int64_t id, const std::string& method) const {
    std::vector<proto::Json> out;
    const auto it = by_job_.find(id);
    if (it == by_job_.end()) return out;
    for (const proto::Json& n : it->second) {
      if (n.at("method").get<std::string>() == method) out.push_back(n);
    }
    return out;
  }

  std::mutex mutex_;
  std::condition_variable changed_;
  std::map<std::int64_t, std::vector<proto::Json>> by_job_;
};

// The value of a future within kBound; a deadlock aborts the test program (a failure) rather
// than blocking it forever.
template <typename T>
T GetWithin(std::future<T>& future, const char* what) {
  if (future.wait_for(kBound) != std::future_status::ready) {
    std::fprintf(stderr, "%s: no answer within %lld s: aborting\n", what,
                 static_cast<long long>(kBound.count()));
    std::abort();
  }
  return future.get();
}

// Whether `done` holds within `bound` (polled every 5 ms).
inline bool WaitUntil(const std::function<bool()>& done, std::chrono::seconds bound) {
  const auto deadline = std::chrono::steady_clock::now() + bound;
  while (!done() && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  return done();
}

class SchedulerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("springfit-scheduler-" +
            std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    path_ = (dir_ / "jobs.db").string();
    scene_ = EndlessScene();
    genes_ = Problem::Build(scene_).gene_count();
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  NewJob Job(const std::string& label, int priority = 0) const {
    NewJob j;
    j.record.label = label;
    j.record.priority = priority;
    j.record.seed = scene_.search.seed;
    j.record.scene_name = scene_.name;
    j.record.genes = genes_;
    j.record.strategy = "paper";
    j.record.max_generations = scene_.search.max_generations;
    j.record.created_at = 1.7e9;
    j.scene_json = proto::SceneToJson(scene_).dump();
    return j;
  }

  static SchedulerOptions Options(int max_running) {
    SchedulerOptions o;
    o.workers = 2;
    o.max_running = max_running;
    return o;
  }
  // Leases of 2 s renewed every 0.2 s, for the tests of leases lapsing. (Ten heartbeats:
  // under ThreadSanitizer on a slow turn of a 2-core machine a 1 s lease lapsed between two
  // renewals, a claim the test did not ask.)
  static SchedulerOptions ShortLeases(int max_running) {
    SchedulerOptions o = Options(max_running);
    o.lease_seconds = 2.0;
    o.heartbeat_seconds = 0.2;
    return o;
  }

  // An endless job that runs until cancelled within a test of a minute. (The endless grid
  // breeds a million generations in about 5 s here: a larger budget.)
  std::int64_t CreateLongJob(SqliteStore& sqlite, const std::string& label, int priority = 0) {
    scene_.search.max_generations = 100000000;
    scene_.search.max_seconds = 60.0;
    return sqlite.CreateJob(Job(label, priority), 100).job.id;
  }

  // The job's one job.finished notification, with state "cancelled".
  static void ExpectFinishedOnceCancelled(Notifications& inbox, std::int64_t id) {
    const std::vector<proto::Json> finished = inbox.Of(id, "job.finished");
    ASSERT_EQ(finished.size(), 1u) << "job " << id;
    EXPECT_EQ(finished[0].at("params").at("state").get<std::string>(), "cancelled") << "job " << id;
    EXPECT_EQ(finished[0].at("params").at("job_id").get<std::int64_t>(), id);
  }

  // Nothing queued or running, in the store and in the scheduler.
  static void ExpectNothingLeft(SqliteStore& store, Scheduler& scheduler,
                                const std::vector<std::int64_t>& ids) {
    EXPECT_EQ(store.CountQueued(), 0);
    EXPECT_TRUE(store.UnfinishedJobs().empty());
    EXPECT_EQ(scheduler.running(), 0);
    for (const std::int64_t id : ids) {
      EXPECT_FALSE(scheduler.IsRunningHere(id)) << "job " << id;
      EXPECT_EQ(scheduler.Cancel(id), Scheduler::CancelOutcome::kNotActive) << "job " << id;
    }
  }

  std::filesystem::path dir_;
  std::string path_;
  Scene scene_;
  int genes_ = 0;
};

}  // namespace springfit::server
