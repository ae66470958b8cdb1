// The scheduler's queue under cancellation: a job cancelled at the moment a runner claims it,
// a job cancelled before any runner starts, and many jobs cancelled while several runners
// claim them. Every job must end cancelled, finished exactly once (one MarkFinished, one
// job.finished), never run to completion, never be lost (left queued or running).
//
// The claim is one store call (ClaimNext); HookedStore (scheduler_test_support.h) runs a hook
// right after it returns, before the runner has registered the job, so "cancelled at the
// moment of the claim" is reproduced deterministically; the many-jobs test races the two
// sides for real.
#include "server/jobs/scheduler.h"

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <future>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "proto/job.h"
#include "proto/rpc.h"
#include "proto/scene_codec.h"
#include "proto/search_codec.h"
#include "server/store/sqlite_store.h"
#include "tests/server/scheduler_test_support.h"
#include "tests/test_scenes.h"

namespace springfit::server {
namespace {

using proto::Json;

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
