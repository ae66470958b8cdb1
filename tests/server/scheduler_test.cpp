// The scheduler's runs (server/jobs/scheduler.h): the problem a submission prepared, a
// shutdown inside a generation, leases that lapse and are claimed again (by the same daemon,
// with a stale renewal in flight), and watched jobs followed through the store. The queue
// under cancellation is scheduler_cancel_test.cpp's; what both share,
// scheduler_test_support.h.
#include "server/jobs/scheduler.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <new>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <SQLiteCpp/SQLiteCpp.h>
#include <gtest/gtest.h>

#include "proto/scene_codec.h"
#include "server/store/sqlite_store.h"
#include "tests/server/scheduler_test_support.h"
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
  // The job's two claims are the test's; a third (a heartbeat that a loaded machine starved
  // past the new lease) is never made, so the new run must go on by itself: a run the stale
  // "not held" of the old claim stopped would not be running here, nor writing.
  store.LimitClaims(2);
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
  // Three leases' worth of time: the new run goes on (here, and writing under its own epoch).
  const std::size_t writes_before = store.ProgressEpochs(id).size();
  std::this_thread::sleep_for(std::chrono::seconds(6));
  EXPECT_EQ(claims(), 2);
  EXPECT_TRUE(scheduler.IsRunningHere(id));
  const std::vector<std::int64_t> epochs = store.ProgressEpochs(id);
  EXPECT_GT(epochs.size(), writes_before) << "the new run stopped writing";
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

}  // namespace
}  // namespace springfit::server
