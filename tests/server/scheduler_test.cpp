// The scheduler's queue under cancellation: a job cancelled at the moment a runner claims it,
// a job cancelled before any runner starts, and many jobs cancelled while several runners
// claim them. Every job must end cancelled, finished exactly once (one MarkFinished, one
// job.finished), never run to completion, never be lost (left queued or running).
//
// The claim is one store call (ClaimNext); HookedStore runs a hook right after it returns,
// before the runner has registered the job, so "cancelled at the moment of the claim" is
// reproduced deterministically; the many-jobs test races the two sides for real.
#include "server/jobs/scheduler.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <future>
#include <map>
#include <mutex>
#include <new>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <SQLiteCpp/SQLiteCpp.h>
#include <gtest/gtest.h>

#include "proto/job.h"
#include "proto/rpc.h"
#include "proto/scene_codec.h"
#include "proto/search_codec.h"
#include "server/store/forwarding_store.h"
#include "server/store/sqlite_store.h"
#include "tests/test_scenes.h"

// Address reuse on demand. Whether a block just freed is handed out again at once is up to
// the allocator (glibc's per-thread caches often do, unless another allocation of its size
// class came first; a sanitizer's quarantine never does). While a ReuseFreedBlocks lives, the
// last block of each size that `delete` frees is handed to the next `new` of that exact size,
// so that an object made right after one of its type was destroyed sits at its address.
namespace reuse {
std::atomic<bool> armed{false};
std::mutex mutex;
std::map<std::size_t, void*>* held = nullptr;  // under mutex, while armed
// The map's own nodes come and go through plain malloc and free.
thread_local bool inside = false;

void* Take(std::size_t n) {
  if (!armed.load() || inside) return nullptr;
  std::lock_guard lock(mutex);
  if (!held) return nullptr;
  inside = true;
  void* p = nullptr;
  if (const auto it = held->find(n); it != held->end()) {
    p = it->second;
    held->erase(it);
  }
  inside = false;
  return p;
}

bool Keep(void* p, std::size_t n) {
  if (!armed.load() || inside) return false;
  std::lock_guard lock(mutex);
  if (!held) return false;
  inside = true;
  const auto [it, kept] = held->try_emplace(n, p);
  if (!kept) {
    std::free(it->second);
    it->second = p;
  }
  inside = false;
  return true;
}
}  // namespace reuse

void* operator new(std::size_t n) {
  if (void* p = reuse::Take(n)) return p;
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t n) noexcept {
  if (p && !reuse::Keep(p, n)) std::free(p);
}

namespace springfit::server {
namespace {
using proto::Json;

class ReuseFreedBlocks {
 public:
  ReuseFreedBlocks() {
    std::lock_guard lock(reuse::mutex);
    reuse::held = new std::map<std::size_t, void*>();
    reuse::armed.store(true);
  }
  ~ReuseFreedBlocks() {
    std::map<std::size_t, void*>* held = nullptr;
    {
      std::lock_guard lock(reuse::mutex);
      reuse::armed.store(false);
      std::swap(held, reuse::held);
    }
    for (const auto& [size, p] : *held) std::free(p);
    delete held;
  }
  ReuseFreedBlocks(const ReuseFreedBlocks&) = delete;
  ReuseFreedBlocks& operator=(const ReuseFreedBlocks&) = delete;
};

constexpr std::chrono::seconds kBound{60};

// A small scene whose search cannot end by itself within a test: its training springs are
// half as stiff as the reference's, so no topology reproduces the reference (the target is
// never reached), nothing stops it for stalling, and its generation budget is out of reach.
// Only a cancel ends it. max_seconds bounds the damage of a lost cancel: such a job ends
// "succeeded" (time limit) after 20 s, which the tests report, instead of running forever.
Scene EndlessScene() {
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

  std::optional<Claim> ClaimNext(const std::string& owner, double lease_seconds) override {
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
    return [this, id](const Json& n) {
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
  std::vector<Json> Of(std::int64_t id, const std::string& method) {
    std::lock_guard lock(mutex_);
    return OfLocked(id, method);
  }

 private:
  std::vector<Json> OfLocked(std::int64_t id, const std::string& method) const {
    std::vector<Json> out;
    const auto it = by_job_.find(id);
    if (it == by_job_.end()) return out;
    for (const Json& n : it->second) {
      if (n.at("method").get<std::string>() == method) out.push_back(n);
    }
    return out;
  }

  std::mutex mutex_;
  std::condition_variable changed_;
  std::map<std::int64_t, std::vector<Json>> by_job_;
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
bool WaitUntil(const std::function<bool()>& done, std::chrono::seconds bound) {
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
    const std::vector<Json> finished = inbox.Of(id, "job.finished");
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

TEST_F(SchedulerTest, AJobCancelledAsARunnerClaimsItEndsCancelledAtGenerationZero) {
  SqliteStore sqlite(path_);
  HookedStore store(sqlite);
  const std::int64_t id = sqlite.CreateJob(Job("claimed"), 100).job.id;
  store.Arm(id);
  // Declared before the scheduler, which calls into them until it is destroyed.
  Notifications inbox;
  std::atomic<int> outcome{-1};
  Scheduler scheduler(store, Options(1));
  scheduler.Watch(id, inbox.For(id));
  store.on_claim = [&](std::int64_t claimed) {
    // The runner has taken the job off the queue and has not read it yet.
    outcome.store(static_cast<int>(scheduler.Cancel(claimed)));
  };
  // Prepared, as a submission here leaves it: the run starts at once, with no preparation
  // (a cancel during one ends the job without a result: the test after this one).
  scheduler.JobSubmitted(id, std::make_shared<const Problem>(scene_));
  scheduler.Start();
  ASSERT_TRUE(inbox.WaitFinished({id})) << "no job.finished within 60 s";
  ASSERT_TRUE(scheduler.Stop(std::chrono::seconds(30)));

  // The cancel found the job claimed (running, not queued): the runner must see the flag.
  EXPECT_EQ(outcome.load(), static_cast<int>(Scheduler::CancelOutcome::kCancelling));
  const std::optional<JobRecord> job = sqlite.GetJob(id);
  ASSERT_TRUE(job);
  EXPECT_EQ(job->state, JobState::kCancelled) << proto::JobStateName(job->state);
  EXPECT_GT(job->started_at, 0.0);  // it was claimed, so it started...
  EXPECT_GT(job->finished_at, 0.0);
  EXPECT_EQ(store.Finishes(id), std::vector<JobState>{JobState::kCancelled});
  ExpectFinishedOnceCancelled(inbox, id);
  // ... and stopped at its first look at the flag: at the end of the initial population (or
  // before it, on a machine so loaded that the progress beat due a second into the run came
  // first). Either way no generation was bred.
  const std::optional<std::string> result = sqlite.GetResult(id);
  ASSERT_TRUE(result);
  const Json r = proto::ParseJson(*result);
  EXPECT_EQ(r.at("stop").get<std::string>(), "cancelled");
  EXPECT_EQ(r.at("generations").get<int>(), 0);
  EXPECT_EQ(r.at("job_id").get<std::int64_t>(), id);
  const std::vector<TraceRow> trace = sqlite.GetTrace(id, -1, 100);
  ASSERT_LE(trace.size(), 1u);
  if (!trace.empty()) {
    EXPECT_EQ(trace[0].generation, 0);  // a cancelled job's last row is kept
  }
  // Generation 0 was announced if it was reached, and its wire form reads back as a row.
  const std::vector<Json> progress = inbox.Of(id, "job.progress");
  ASSERT_EQ(progress.size(), trace.size());
  for (const Json& n : progress) {
    Json row = proto::ParseJson(proto::rpc::Serialize(n)).at("params");
    EXPECT_EQ(row.at("job_id").get<std::int64_t>(), id);
    row.erase("job_id");
    row.erase("max_generations");
    EXPECT_EQ(proto::TraceRowFromJson(row, "params").generation, 0);
  }
  ExpectNothingLeft(sqlite, scheduler, {id});
}

// A job whose problem its runner prepares (resumed after a restart, or queued by another
// daemon) takes seconds to prepare when its scene is large: a cancel stops the preparation
// between the reference's Newton iterations, and the job ends cancelled without a result.
TEST_F(SchedulerTest, AJobCancelledWhileItsRunnerPreparesItEndsWithoutAResult) {
  SqliteStore sqlite(path_);
  HookedStore store(sqlite);
  Scene large = springfit::testing::GridScene(2, 100);  // 10,000 nodes: about a second
  large.search.strategy = Strategy::kPaper;
  NewJob job = Job("large");
  job.scene_json = proto::SceneToJson(large).dump();
  const std::int64_t id = sqlite.CreateJob(job, 100).job.id;
  store.Arm(id);
  Notifications inbox;
  Scheduler scheduler(store, Options(1));
  scheduler.Watch(id, inbox.For(id));
  store.on_claim = [&](std::int64_t claimed) { scheduler.Cancel(claimed); };
  scheduler.Start();
  ASSERT_TRUE(inbox.WaitFinished({id})) << "no job.finished within 60 s";
  ASSERT_TRUE(scheduler.Stop(std::chrono::seconds(30)));
  EXPECT_EQ(sqlite.GetJob(id)->state, JobState::kCancelled);
  EXPECT_EQ(store.Finishes(id), std::vector<JobState>{JobState::kCancelled});
  ExpectFinishedOnceCancelled(inbox, id);
  EXPECT_FALSE(sqlite.GetResult(id)) << "the search ran: the preparation was not stopped";
  EXPECT_TRUE(sqlite.GetTrace(id, -1, 100).empty());
  ExpectNothingLeft(sqlite, scheduler, {id});
}

TEST_F(SchedulerTest, AJobCancelledWhileQueuedIsNeverClaimed) {
  SqliteStore sqlite(path_);
  HookedStore store(sqlite);
  // `first` would be claimed first (higher priority) if it were still queued.
  const JobRecord first = sqlite.CreateJob(Job("first", 5), 100).job;
  const std::int64_t second = sqlite.CreateJob(Job("second", 0), 100).job.id;
  Notifications inbox;
  Scheduler scheduler(store, Options(1));
  scheduler.Watch(first.id, inbox.For(first.id));
  scheduler.Watch(second, inbox.For(second));
  EXPECT_EQ(scheduler.Cancel(first.id), Scheduler::CancelOutcome::kCancelled);
  EXPECT_EQ(sqlite.GetJob(first.id)->state, JobState::kCancelled);
  ExpectFinishedOnceCancelled(inbox, first.id);

  store.Arm(second);
  store.on_claim = [&](std::int64_t id) { scheduler.Cancel(id); };
  scheduler.Start();
  ASSERT_TRUE(inbox.WaitFinished({second})) << "no job.finished within 60 s";
  ASSERT_TRUE(scheduler.Stop(std::chrono::seconds(30)));

  EXPECT_EQ(store.Claimed(), std::vector<std::int64_t>{second}) << "the cancelled job was claimed";
  const std::optional<JobRecord> never = sqlite.GetJob(first.id);
  ASSERT_TRUE(never);
  EXPECT_EQ(never->state, JobState::kCancelled);
  EXPECT_EQ(never->started_at, 0.0);
  EXPECT_FALSE(sqlite.GetResult(first.id));
  EXPECT_TRUE(sqlite.GetTrace(first.id, -1, 100).empty());
  EXPECT_EQ(store.Finishes(first.id), std::vector<JobState>{JobState::kCancelled});
  ExpectFinishedOnceCancelled(inbox, first.id);
  EXPECT_TRUE(inbox.Of(first.id, "job.progress").empty());

  EXPECT_EQ(sqlite.GetJob(second)->state, JobState::kCancelled);
  EXPECT_EQ(store.Finishes(second), std::vector<JobState>{JobState::kCancelled});
  ExpectFinishedOnceCancelled(inbox, second);
  ExpectNothingLeft(sqlite, scheduler, {first.id, second});
}

// A job queued with the problem its submission prepared runs on it: its scene is not read back
// from the store and prepared again. One queued without it (a restart, another daemon) is.
TEST_F(SchedulerTest, AJobRunsOnTheProblemItsSubmissionPrepared) {
  SqliteStore sqlite(path_);
  HookedStore store(sqlite);
  const JobRecord prepared_job = sqlite.CreateJob(Job("prepared", 5), 100).job;
  const JobRecord stored_job = sqlite.CreateJob(Job("stored", 0), 100).job;
  Notifications inbox;
  Scheduler scheduler(store, Options(1));
  scheduler.Watch(prepared_job.id, inbox.For(prepared_job.id));
  scheduler.Watch(stored_job.id, inbox.For(stored_job.id));
  scheduler.JobSubmitted(prepared_job.id, std::make_shared<const Problem>(scene_));
  scheduler.JobSubmitted(stored_job.id);
  store.Arm(prepared_job.id);
  store.Arm(stored_job.id);
  store.on_claim = [&](std::int64_t id) { scheduler.Cancel(id); };  // endless otherwise
  scheduler.Start();
  ASSERT_TRUE(inbox.WaitFinished({prepared_job.id, stored_job.id}))
      << "no job.finished within 60 s";
  ASSERT_TRUE(scheduler.Stop(std::chrono::seconds(30)));
  EXPECT_EQ(store.SceneReads(prepared_job.id), 0);
  EXPECT_EQ(store.SceneReads(stored_job.id), 1);
  EXPECT_EQ(sqlite.GetJob(prepared_job.id)->state, JobState::kCancelled);
  EXPECT_EQ(sqlite.GetJob(stored_job.id)->state, JobState::kCancelled);
}

// A shutdown that lands inside a step leaves the job to resume, never cancelled: with the
// memetic GA (strategy default) the step is most often a local search, which keeps what it found
// and reports its generation; that report must not clear the shutdown. Two rounds, since
// where the stop lands is up to the clock.
TEST_F(SchedulerTest, AShutdownInsideAGenerationLeavesTheJobToResume) {
  for (int round = 0; round < 2; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    const std::string path = (dir_ / ("shutdown-" + std::to_string(round) + ".db")).string();
    SqliteStore sqlite(path);
    HookedStore store(sqlite);
    NewJob job = Job("memetic");
    // Generations long enough (a local search over a 12x12 grid's 500 genes at the wrong
    // stiffness) for the stop to land inside one: a beat comes only 0.25 s after a report.
    Scene memetic = springfit::testing::GridScene(2, 12);
    memetic.training_stiffness = 0.5;
    memetic.search = scene_.search;
    memetic.search.strategy = Strategy::kDefault;
    job.scene_json = proto::SceneToJson(memetic).dump();
    job.record.strategy = "default";
    const std::int64_t id = sqlite.CreateJob(job, 100).job.id;
    Notifications inbox;
    Scheduler scheduler(store, Options(1));
    scheduler.Watch(id, inbox.For(id));
    scheduler.Start();
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (inbox.Of(id, "job.progress").empty() && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(1 + round));
    ASSERT_FALSE(inbox.Of(id, "job.progress").empty()) << "the job made no progress in 30 s";
    std::this_thread::sleep_for(std::chrono::milliseconds(300 + 97 * round));
    ASSERT_TRUE(scheduler.Stop(std::chrono::seconds(30)));
    EXPECT_EQ(sqlite.GetJob(id)->state, JobState::kRunning) << "not left to resume";
    EXPECT_TRUE(store.Finishes(id).empty());
    EXPECT_TRUE(inbox.Of(id, "job.finished").empty());
  }
}

// A heartbeat that stalls past the lease while a runner is idle: the store hands the job out
// again, to the same daemon. The run going on here stops first (its lease is lost), the new
// claim resumes the job, and from then on one run holds it: its heartbeat keeps its lease, so
// it is not claimed a third time, and no write of the old run follows the new run's first.
TEST_F(SchedulerTest, AJobItsOwnDaemonClaimsAgainRunsOnceAtATime) {
  SqliteStore sqlite(path_);
  HookedStore store(sqlite);
  const std::int64_t id = CreateLongJob(sqlite, "stalled");
  const SchedulerOptions options = ShortLeases(2);
  Notifications inbox;
  Scheduler scheduler(store, options);
  scheduler.Watch(id, inbox.For(id));
  scheduler.Start();
  const auto claims = [&] { return store.ClaimsOf(id); };
  ASSERT_TRUE(
      WaitUntil([&] { return !store.ProgressEpochs(id).empty(); }, std::chrono::seconds(30)));
  // The heartbeat stalls until the lapsed lease has been claimed again.
  store.StallNextRenewal([&] { return claims() >= 2; });
  ASSERT_TRUE(WaitUntil([&] { return claims() == 2; }, std::chrono::seconds(30)))
      << "the idle runner did not claim the lapsed job";
  const std::int64_t first_epoch = store.ProgressEpochs(id).front();
  ASSERT_TRUE(WaitUntil(
      [&] {
        const auto epochs = store.ProgressEpochs(id);
        return std::count_if(epochs.begin(), epochs.end(),
                             [&](std::int64_t e) { return e != first_epoch; }) >= 2;
      },
      std::chrono::seconds(30)))
      << "the new claim made no progress";
  // Three leases' worth of time: the new run's heartbeat keeps its lease.
  std::this_thread::sleep_for(std::chrono::seconds(6));
  EXPECT_EQ(claims(), 2);
  EXPECT_TRUE(scheduler.IsRunningHere(id));
  const std::vector<std::int64_t> epochs = store.ProgressEpochs(id);
  const auto first_new =
      std::find_if(epochs.begin(), epochs.end(), [&](std::int64_t e) { return e != first_epoch; });
  EXPECT_TRUE(std::all_of(first_new, epochs.end(), [&](std::int64_t e) { return e == *first_new; }))
      << "a write of the old run after the new run's first";
  EXPECT_EQ(scheduler.Cancel(id), Scheduler::CancelOutcome::kCancelling);
  ASSERT_TRUE(inbox.WaitFinished({id}));
  ExpectFinishedOnceCancelled(inbox, id);
  ASSERT_TRUE(scheduler.Stop(std::chrono::seconds(30)));
  ExpectNothingLeft(sqlite, scheduler, {id});
}

// A heartbeat that stalls on a run's renewal while that run loses its lease (to another
// daemon, which lets it go) and the same runner claims the job again: the new run's slot may
// sit where the old one did. The stalled renewal, answered "not held" for the old claim, must
// not stop the new run, whose lease it is not: the new run goes on, and the job is not claimed
// a third time.
TEST_F(SchedulerTest, AStaleRenewalDoesNotStopTheNextRunOfTheSameJob) {
  SqliteStore sqlite(path_);
  HookedStore store(sqlite);
  const std::int64_t id = CreateLongJob(sqlite, "reclaimed");
  // One runner: the old run's slot is freed and the new one made on the same thread.
  SchedulerOptions options = ShortLeases(1);
  options.poll_seconds = 0.1;
  Notifications inbox;
  Scheduler scheduler(store, options);
  scheduler.Watch(id, inbox.For(id));
  scheduler.Start();
  ASSERT_TRUE(
      WaitUntil([&] { return !store.ProgressEpochs(id).empty(); }, std::chrono::seconds(30)));
  // The new run's slot is made where the old run's was (reproduced, not left to the allocator).
  const ReuseFreedBlocks reuse_addresses;
  // The next renewal (the old run's) stalls until the job runs here again.
  store.StallNextRenewal([&] { return store.ClaimsOf(id) >= 2 && scheduler.IsRunningHere(id); });
  std::optional<Claim> other;
  ASSERT_TRUE(WaitUntil(
      [&] {
        if (!other) other = sqlite.ClaimNext("other-daemon", 30.0);
        return other.has_value();
      },
      std::chrono::seconds(30)))
      << "the stalled lease did not lapse";
  ASSERT_TRUE(WaitUntil([&] { return !scheduler.IsRunningHere(id); }, std::chrono::seconds(30)))
      << "the old run did not stop on losing its lease";
  sqlite.ReleaseLease(other->lease);
  ASSERT_TRUE(WaitUntil([&] { return store.ClaimsOf(id) == 2; }, std::chrono::seconds(30)))
      << "the released job was not claimed again";
  const std::int64_t new_epoch = other->lease.epoch + 1;
  // Three leases' worth of time after the stalled renewal returned.
  std::this_thread::sleep_for(std::chrono::seconds(6));
  EXPECT_TRUE(scheduler.IsRunningHere(id)) << "the new run was stopped";
  EXPECT_EQ(store.ClaimsOf(id), 2);
  EXPECT_EQ(store.ProgressEpochs(id).back(), new_epoch);
  EXPECT_EQ(scheduler.Cancel(id), Scheduler::CancelOutcome::kCancelling);
  ASSERT_TRUE(inbox.WaitFinished({id}));
  ExpectFinishedOnceCancelled(inbox, id);
  ASSERT_TRUE(scheduler.Stop(std::chrono::seconds(30)));
  ExpectNothingLeft(sqlite, scheduler, {id});
}

// Watched jobs that run elsewhere are followed through the store. One whose row is damaged
// (quarantined when read) ends its watch with job.gone saying so; the jobs watched after it
// are followed on: one finished by another daemon gets its job.finished.
TEST_F(SchedulerTest, AWatchedJobWhoseRowIsDamagedEndsItsWatchAndTheOthersAreFollowed) {
  SqliteStore sqlite(path_);
  const std::int64_t busy = CreateLongJob(sqlite, "busy", 10);
  const std::int64_t damaged = sqlite.CreateJob(Job("damaged", 0), 100).job.id;
  const std::int64_t elsewhere = sqlite.CreateJob(Job("elsewhere", 5), 100).job.id;
  Notifications inbox;
  Scheduler scheduler(sqlite, Options(1));  // its one runner busy with `busy`
  scheduler.Start();
  ASSERT_TRUE(WaitUntil([&] { return scheduler.IsRunningHere(busy); }, std::chrono::seconds(30)));
  scheduler.Watch(damaged, inbox.For(damaged));
  scheduler.Watch(elsewhere, inbox.For(elsewhere));
  {
    SQLite::Database db(path_, SQLite::OPEN_READWRITE);
    db.setBusyTimeout(30000);  // (the running job writes meanwhile)
    db.exec("UPDATE jobs SET progress = '{not json' WHERE id = " + std::to_string(damaged));
  }
  const std::optional<Claim> other = sqlite.ClaimNext("other-daemon", 30.0);
  ASSERT_TRUE(other && other->job.id == elsewhere);
  sqlite.MarkFinished(other->lease, {JobState::kSucceeded, "", "{}", std::nullopt, 2e9, ""});
  EXPECT_TRUE(inbox.WaitFinished({elsewhere})) << "the job after the damaged one was not followed";
  ASSERT_TRUE(
      WaitUntil([&] { return !inbox.Of(damaged, "job.gone").empty(); }, std::chrono::seconds(30)));
  const std::string message =
      inbox.Of(damaged, "job.gone")[0].at("params").at("message").get<std::string>();
  EXPECT_NE(message.find("job " + std::to_string(damaged) + " is quarantined"), std::string::npos)
      << message;
  EXPECT_EQ(scheduler.Cancel(busy), Scheduler::CancelOutcome::kCancelling);
  ASSERT_TRUE(scheduler.Stop(std::chrono::seconds(30)));
}

// The race for real: 30 endless jobs, 3 runners claiming from the moment Start() returns, and
// two threads cancelling every job, one in submission order and one in reverse. Where each
// cancel lands (queued, claimed, running, finished) is up to the threads; whatever it is, the
// end must be consistent.
TEST_F(SchedulerTest, JobsCancelledWhileRunnersClaimThemAllEndCancelledExactlyOnce) {
  constexpr int kJobs = 30;
  SqliteStore sqlite(path_);
  HookedStore store(sqlite);
  std::vector<std::int64_t> ids;
  for (int i = 0; i < kJobs; ++i)
    ids.push_back(sqlite.CreateJob(Job("race-" + std::to_string(i)), 100).job.id);
  Notifications inbox;
  Scheduler scheduler(store, Options(3));
  for (const std::int64_t id : ids) scheduler.Watch(id, inbox.For(id));

  using Outcomes = std::vector<Scheduler::CancelOutcome>;
  scheduler.Start();  // the runners claim from the store at once
  auto forward = std::async(std::launch::async, [&] {
    Outcomes out;
    for (const std::int64_t id : ids) out.push_back(scheduler.Cancel(id));
    return out;
  });
  auto backward = std::async(std::launch::async, [&] {
    Outcomes out;
    for (auto it = ids.rbegin(); it != ids.rend(); ++it) out.push_back(scheduler.Cancel(*it));
    std::reverse(out.begin(), out.end());  // in submission order, like `forward`'s
    return out;
  });
  const Outcomes by_forward = GetWithin(forward, "cancelling in submission order");
  const Outcomes by_backward = GetWithin(backward, "cancelling in reverse order");
  ASSERT_TRUE(inbox.WaitFinished(ids)) << "some job did not finish within 60 s";
  ASSERT_TRUE(scheduler.Stop(std::chrono::seconds(30)));

  using Outcome = Scheduler::CancelOutcome;
  int cancelled_queued = 0;
  int cancelled_running = 0;
  for (int i = 0; i < kJobs; ++i) {
    const std::int64_t id = ids[i];
    SCOPED_TRACE("job " + std::to_string(id));
    const Outcome a = by_forward[i];
    const Outcome b = by_backward[i];
    // A job is queued or running until cancelled, so the first cancel always finds it active;
    // and only one cancel can take it off the queue.
    EXPECT_TRUE(a != Outcome::kNotActive || b != Outcome::kNotActive);
    EXPECT_FALSE(a == Outcome::kCancelled && b == Outcome::kCancelled);

    const std::optional<JobRecord> job = sqlite.GetJob(id);
    ASSERT_TRUE(job);
    EXPECT_EQ(job->state, JobState::kCancelled) << proto::JobStateName(job->state);
    EXPECT_EQ(store.Finishes(id), std::vector<JobState>{JobState::kCancelled});
    ExpectFinishedOnceCancelled(inbox, id);
    const std::optional<std::string> result = sqlite.GetResult(id);
    if (a == Outcome::kCancelled || b == Outcome::kCancelled) {
      // Taken off the queue: no runner ever had it.
      ++cancelled_queued;
      EXPECT_EQ(job->started_at, 0.0);
      EXPECT_FALSE(result);
      EXPECT_TRUE(sqlite.GetTrace(id, -1, 100).empty());
      EXPECT_TRUE(inbox.Of(id, "job.progress").empty());
    } else {
      // Claimed: it ran, and stopped early with its best so far. Its stored rows and its
      // announcements agree: both empty only when stopped before generation 0 ended. Or the
      // cancel came before its runner had prepared the scene: no result, nothing announced.
      ++cancelled_running;
      EXPECT_GT(job->started_at, 0.0);
      if (!result) {
        EXPECT_TRUE(sqlite.GetTrace(id, -1, 100).empty());
        EXPECT_TRUE(inbox.Of(id, "job.progress").empty());
        continue;
      }
      EXPECT_EQ(proto::ParseJson(*result).at("stop").get<std::string>(), "cancelled");
      EXPECT_EQ(sqlite.GetTrace(id, -1, 100).empty(), inbox.Of(id, "job.progress").empty());
    }
  }
  EXPECT_EQ(cancelled_queued + cancelled_running, kJobs);
  std::printf("%d jobs cancelled while queued, %d while claimed or running\n", cancelled_queued,
              cancelled_running);

  // The store's counts add up: every job cancelled, none in any other state.
  for (const JobState state : {JobState::kQueued, JobState::kRunning, JobState::kSucceeded,
                               JobState::kFailed, JobState::kCancelled}) {
    JobFilter filter;
    filter.state = state;
    filter.limit = 1000;
    EXPECT_EQ(sqlite.ListJobs(filter).jobs.size(),
              state == JobState::kCancelled ? static_cast<std::size_t>(kJobs) : 0u)
        << proto::JobStateName(state);
  }
  ExpectNothingLeft(sqlite, scheduler, ids);
}

}  // namespace
}  // namespace springfit::server
