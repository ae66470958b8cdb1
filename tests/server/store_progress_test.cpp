// The store suite (store_suite_test.cpp) on a job's progress: trace rows, improvements,
// checkpoints, rewinds and the finish; a failed write loses nothing and the job resumes to the
// same result.
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "proto/outcome_codec.h"
#include "proto/scene_codec.h"
#include "server/jobs/scheduler.h"
#include "server/store/forwarding_store.h"
#include "server/store/job_store.h"
#include "tests/server/store_suite_test_support.h"
#include "tests/test_scenes.h"

namespace springfit::server {
namespace {

using namespace std::chrono_literals;

TEST_P(StoreSuite, ProgressCheckpointRewindAndFinish) {
  const std::int64_t id = Create("p");
  const Lease lease = ClaimOne("d").lease;
  ProgressBatch first;
  for (int g = 0; g <= 4; ++g) first.trace.push_back(Row(g, 1.0 / (g + 1)));
  first.improvements.push_back(
      {0, 0.1, 2.0, 1.0, -1, 1, Genome{1, 0, 1, 1, 0, 0, 0, 0, 1, 1, 1, 0}});
  first.latest = first.trace.back();
  first.checkpoint = std::string("state\0with\0zeros\xff", 17);
  first.checkpoint_generation = 4;
  store_->SaveProgress(lease, first);
  ProgressBatch second;
  for (int g = 5; g <= 6; ++g) second.trace.push_back(Row(g, 0.1));
  second.improvements.push_back({5, 0.5, 0.2, 0.1, 3, 1, Genome(12, 1)});
  second.latest = second.trace.back();
  store_->SaveProgress(lease, second);

  const auto job = store_->GetJob(id);
  EXPECT_EQ(job->state, JobState::kRunning);
  EXPECT_EQ(job->checkpoint_generation, 4);
  ASSERT_TRUE(job->progress);
  EXPECT_EQ(job->progress->generation, 6);
  EXPECT_EQ(*store_->GetCheckpoint(id), std::string("state\0with\0zeros\xff", 17));
  const auto all = store_->GetTrace(id, -1, 100);
  ASSERT_EQ(all.size(), 7u);
  for (int g = 0; g <= 4; ++g) {
    EXPECT_TRUE(all[g].SameSearch(first.trace[g])) << "generation " << g;
    EXPECT_EQ(all[g].wall_seconds, first.trace[g].wall_seconds);  // every bit of a double
  }
  EXPECT_TRUE(std::isinf(all[2].mean_cost));
  const auto page = store_->GetTrace(id, 2, 2);
  ASSERT_EQ(page.size(), 2u);
  EXPECT_EQ(page[0].generation, 3);
  EXPECT_EQ(store_->GetTrace(id, -1, 1)[0].missing, -1);  // null stays unknown

  // Resuming from the checkpoint at 4 drops what came after it.
  store_->RewindTo(lease, 4);
  EXPECT_EQ(store_->GetTrace(id, -1, 100).size(), 5u);
  const auto improvements = store_->GetImprovements(id);
  ASSERT_EQ(improvements.size(), 1u);
  // (Paged: the newest alone, and none after it.)
  ASSERT_EQ(store_->GetImprovements(id, {.last = true}).size(), 1u);
  EXPECT_EQ(store_->GetImprovements(id, {.last = true})[0].generation, improvements[0].generation);
  EXPECT_TRUE(store_->GetImprovements(id, {.after = improvements[0].generation}).empty());
  EXPECT_EQ(improvements[0].genome, (Genome{1, 0, 1, 1, 0, 0, 0, 0, 1, 1, 1, 0}));
  EXPECT_EQ(improvements[0].missing, -1);

  // Rows written again after a rewind replace the old ones.
  ProgressBatch again;
  again.trace.push_back(Row(4, 0.01));
  store_->SaveProgress(lease, again);
  EXPECT_EQ(store_->GetTrace(id, 3, 10)[0].best_normalized_error, 0.01);

  // The verdict is kept beside the result and read back with the job (listings).
  Outcome outcome;
  outcome.verdict = Verdict::kUnmetRequest;
  outcome.springs = 759;
  outcome.rms_error = 0.038;
  outcome.unmet = {"spring budget not met"};
  store_->MarkFinished(lease, {JobState::kSucceeded, "", R"({"cost":0})", false, 1.7e9,
                               proto::OutcomeToJson(outcome).dump()});
  EXPECT_FALSE(store_->GetCheckpoint(id));  // a finished job never resumes
  EXPECT_EQ(*store_->GetResult(id), R"({"cost":0})");
  EXPECT_EQ(store_->GetJob(id)->exact, std::optional<bool>(false));
  const std::optional<Outcome> stored = store_->GetJob(id)->outcome;
  ASSERT_TRUE(stored);
  EXPECT_EQ(stored->verdict, Verdict::kUnmetRequest);
  EXPECT_EQ(stored->springs, 759);
  EXPECT_EQ(stored->rms_error, std::optional<double>(0.038));
  EXPECT_EQ(stored->unmet, outcome.unmet);
  EXPECT_EQ(store_->GetJob(id)->state, JobState::kSucceeded);
  EXPECT_TRUE(store_->UnfinishedJobs().empty());
}

// A store that fails the N-th write (fault injection): the write changes nothing and throws
// StoreUnavailable, as a full disk or a lost connection does.
class FailingStore final : public ForwardingStore {
 public:
  FailingStore(JobStore& inner, int fail_at) : ForwardingStore(inner), fail_at_(fail_at) {}
  void SaveProgress(const Lease& lease, const ProgressBatch& batch) override {
    if (++writes_ == fail_at_) throw StoreUnavailable("injected: the disk is full");
    inner_.SaveProgress(lease, batch);
  }
  int writes() const { return writes_.load(); }

 private:
  int fail_at_;
  std::atomic<int> writes_{0};
};

// A job whose store write fails is neither lost nor failed: it stays running in the store,
// its lease lapses, and it is claimed again and resumes from its last checkpoint, ending
// with exactly the trace and result of an uninterrupted run.
TEST_P(StoreSuite, AFailedWriteLosesNothingAndTheJobResumesToTheSameResult) {
  Scene scene = springfit::testing::GridScene(2, 3);
  scene.search.strategy = Strategy::kPaper;
  scene.search.max_generations = 60;
  scene.search.stall_generations = 0;
  scene.training_stiffness = 0.5;  // never exact: the run goes to its generation limit
  scene.search.seed = 11;
  NewJob job = Job("faulty");
  job.scene_json = proto::SceneToJson(scene).dump();
  job.record.strategy = "paper";

  SchedulerOptions options;
  options.workers = 1;
  options.runner.checkpoint_seconds = 0.0;  // a checkpoint, and a write, every generation
  options.lease_seconds = 0.4;
  options.heartbeat_seconds = 0.1;
  options.poll_seconds = 0.05;
  const auto run = [&](JobStore& store) {
    const std::int64_t id = store.CreateJob(job, 100).job.id;
    Scheduler scheduler(store, options);
    scheduler.Start();
    const auto deadline = std::chrono::steady_clock::now() + 60s;
    while (!proto::IsFinal(store.GetJob(id)->state) && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(20ms);
    EXPECT_TRUE(scheduler.Stop(30s));
    return id;
  };
  FailingStore failing(*store_, 20);
  const std::int64_t faulty = run(failing);
  EXPECT_GT(failing.writes(), 20) << "the job did not go on after the failed write";
  const std::int64_t clean = run(*store_);

  const auto a = store_->GetJob(faulty);
  const auto b = store_->GetJob(clean);
  ASSERT_EQ(a->state, JobState::kSucceeded) << a->error;
  ASSERT_EQ(b->state, JobState::kSucceeded) << b->error;
  const auto trace_a = store_->GetTrace(faulty, -1, 1000);
  const auto trace_b = store_->GetTrace(clean, -1, 1000);
  ASSERT_EQ(trace_a.size(), trace_b.size());
  for (std::size_t i = 0; i < trace_a.size(); ++i)
    EXPECT_TRUE(trace_a[i].SameSearchButCacheHits(trace_b[i])) << "generation " << i;
  // The results agree but for wall times, the fitness cache's hits (a resumed job starts
  // with an empty cache) and the job's id.
  proto::Json ra = proto::ParseJson(*store_->GetResult(faulty));
  proto::Json rb = proto::ParseJson(*store_->GetResult(clean));
  for (proto::Json* r : {&ra, &rb}) {
    for (const char* key : {"wall_seconds", "cache_hits", "job_id"}) r->erase(key);
  }
  EXPECT_EQ(ra, rb);
}

}  // namespace
}  // namespace springfit::server
