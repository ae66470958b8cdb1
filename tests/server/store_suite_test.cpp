// One suite, two stores: every behaviour the daemons rely on (server/store/job_store.h), run
// against the embedded SQLite store and against a real PostgreSQL server. The PostgreSQL
// half needs SPRINGFIT_TEST_PG_URL, the URL of a private server that
// tests/server/with_postgres.sh starts around this program; without it those tests fail,
// naming the script, rather than skip. The suite's fixture is store_suite_test_support.h;
// its tests are in the store_*_test.cpp files by subject, and this one holds the jobs'
// records (create, list, prepare, delete) and the suite's instantiation.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "server/store/job_store.h"
#include "tests/server/store_suite_test_support.h"

namespace springfit::server {
namespace {

using namespace std::chrono_literals;

TEST_P(StoreSuite, CreateGetIdempotencyKeysAndTheQueueBound) {
  const auto a = store_->CreateJob(Job("a", 0, "key-1"), 3);
  EXPECT_TRUE(a.created);
  EXPECT_EQ(a.job.state, JobState::kQueued);
  const auto again = store_->CreateJob(Job("different label", 5, "key-1"), 3);
  EXPECT_FALSE(again.created);
  EXPECT_EQ(again.job.id, a.job.id);
  EXPECT_EQ(again.job.label, "a");
  const auto b = store_->CreateJob(Job("b"), 3);
  const auto c = store_->CreateJob(Job("c"), 3);  // no key: never deduplicated
  EXPECT_NE(b.job.id, c.job.id);
  const auto full = store_->CreateJob(Job("d"), 3);
  EXPECT_TRUE(full.queue_full);
  EXPECT_FALSE(full.created);
  EXPECT_EQ(store_->CountQueued(), 3);
  // A retry of an accepted submit is answered even when the queue is full.
  EXPECT_EQ(store_->CreateJob(Job("a", 0, "key-1"), 3).job.id, a.job.id);
  const auto got = store_->GetJob(a.job.id);
  ASSERT_TRUE(got);
  EXPECT_EQ(got->seed, 0xfedcba9876543210ULL);
  EXPECT_EQ(got->idempotency_key, "key-1");
  EXPECT_EQ(store_->GetJob(b.job.id)->idempotency_key, "");
  EXPECT_EQ(*store_->GetScene(a.job.id), R"({"name":"s"})");
  EXPECT_FALSE(store_->GetJob(999));
}

TEST_P(StoreSuite, ListPagesAndFilters) {
  for (int i = 0; i < 7; ++i) Create(i % 2 ? "odd" : "even");
  const Claim first = ClaimOne("d");
  store_->MarkFinished(first.lease, {JobState::kSucceeded, "", "{}", true, 2e9, ""});
  JobFilter f;
  f.limit = 3;
  std::vector<std::int64_t> ids;
  for (int page = 0; page < 10; ++page) {
    const JobPage p = store_->ListJobs(f);
    for (const auto& j : p.jobs) ids.push_back(j.id);
    if (!p.next_cursor) break;
    f.after_id = *p.next_cursor;
  }
  ASSERT_EQ(ids.size(), 7u);
  EXPECT_TRUE(std::is_sorted(ids.begin(), ids.end()));
  JobFilter odd;
  odd.label = "odd";
  EXPECT_EQ(store_->ListJobs(odd).jobs.size(), 3u);
  JobFilter done;
  done.state = JobState::kSucceeded;
  const JobPage finished = store_->ListJobs(done);
  ASSERT_EQ(finished.jobs.size(), 1u);
  EXPECT_EQ(finished.jobs[0].id, first.job.id);
  EXPECT_EQ(finished.jobs[0].exact, std::optional<bool>(true));
  EXPECT_FALSE(finished.next_cursor);
  JobFilter both;
  both.state = JobState::kQueued;
  both.label = "even";
  EXPECT_EQ(store_->ListJobs(both).jobs.size(), 3u);  // the first "even" finished

  // Newest first (the dashboard), paged by the same cursor.
  JobFilter newest;
  newest.newest_first = true;
  newest.limit = 4;
  std::vector<std::int64_t> down;
  for (int page = 0; page < 10; ++page) {
    const JobPage p = store_->ListJobs(newest);
    for (const auto& j : p.jobs) down.push_back(j.id);
    if (!p.next_cursor) break;
    newest.after_id = *p.next_cursor;
  }
  EXPECT_EQ(down, std::vector<std::int64_t>(ids.rbegin(), ids.rend()));
  const std::map<JobState, int> counts = store_->CountJobs();
  EXPECT_EQ(counts, (std::map<JobState, int>{{JobState::kQueued, 6}, {JobState::kSucceeded, 1}}));
}

// A submission being prepared: a job from the start, held by its daemon's lease, never
// claimed; queued (or cancelled) when its preparation ends, or deleted when it was refused,
// or swept once its lease lapsed (the daemon preparing it died).
TEST_P(StoreSuite, PreparingJobsAreHeldListedCancellableAndNeverClaimed) {
  const auto Preparing = [&](const std::string& label, double lease_seconds = 30.0) {
    NewJob job = Job(label);
    job.preparing_owner = "daemon-a";
    job.lease_seconds = lease_seconds;
    return store_->CreateJob(job, 3);
  };
  const auto a = Preparing("a");
  ASSERT_TRUE(a.created);
  EXPECT_EQ(a.job.state, JobState::kPreparing);
  EXPECT_EQ(a.lease.job_id, a.job.id);
  EXPECT_EQ(a.lease.owner, "daemon-a");
  EXPECT_EQ(store_->GetJob(a.job.id)->state, JobState::kPreparing);
  JobFilter preparing;
  preparing.state = JobState::kPreparing;
  EXPECT_EQ(store_->ListJobs(preparing).jobs.size(), 1u);
  EXPECT_EQ(store_->CountJobs()[JobState::kPreparing], 1);
  EXPECT_FALSE(store_->ClaimNext("daemon-b", 30.0)) << "a job being prepared was claimed";
  EXPECT_TRUE(store_->RenewLease(a.lease, 30.0).held);

  // Prepared: queued with what the preparation found, then claimed like any other.
  JobRecord found = a.job;
  found.genes = 4321;
  found.strategy = "hybrid";
  found.max_generations = 77;
  EXPECT_EQ(store_->FinishPreparing(a.lease, found), JobState::kQueued);
  const auto queued = store_->GetJob(a.job.id);
  EXPECT_EQ(queued->state, JobState::kQueued);
  EXPECT_EQ(queued->genes, 4321);
  EXPECT_EQ(queued->strategy, "hybrid");
  EXPECT_EQ(queued->max_generations, 77);
  EXPECT_THROW(store_->FinishPreparing(a.lease, found), LeaseLost) << "prepared twice";
  EXPECT_FALSE(store_->RenewLease(a.lease, 30.0).held) << "a queued job's lease renewed";
  const Claim claim = ClaimOne("daemon-b");
  EXPECT_EQ(claim.job.id, a.job.id);
  EXPECT_EQ(claim.job.genes, 4321);

  // A cancel while it is prepared is a request the preparing daemon's heartbeat reads; the
  // job ends cancelled when the preparation stops (or finishes first: the cancel wins).
  const auto b = Preparing("b");
  EXPECT_EQ(store_->RequestCancel(b.job.id), JobStore::CancelOutcome::kRequested);
  EXPECT_EQ(store_->GetJob(b.job.id)->state, JobState::kPreparing);
  EXPECT_TRUE(store_->RenewLease(b.lease, 30.0).cancel_requested);
  EXPECT_EQ(store_->FinishPreparing(b.lease, b.job), JobState::kCancelled);
  const auto cancelled = store_->GetJob(b.job.id);
  EXPECT_EQ(cancelled->state, JobState::kCancelled);
  EXPECT_GT(cancelled->finished_at, 0.0);
  const auto c = Preparing("c");
  store_->MarkFinished(c.lease, {JobState::kCancelled, "", "", std::nullopt, 2e9, ""});
  EXPECT_EQ(store_->GetJob(c.job.id)->state, JobState::kCancelled);

  // Refused: deleted, by its holder only. Preparing jobs count toward the queue bound.
  const auto d = Preparing("d");
  const auto e = Preparing("e", 0.2);
  EXPECT_TRUE(store_->CreateJob(Job("over"), 2).queue_full) << "d and e were not counted";
  Lease stranger = d.lease;
  stranger.epoch += 1;
  store_->DropPreparing(stranger);
  EXPECT_TRUE(store_->GetJob(d.job.id)) << "dropped by a lease that is not its own";
  store_->DropPreparing(d.lease);
  EXPECT_FALSE(store_->GetJob(d.job.id));
  // e's daemon stopped renewing it: the next claim sweeps it, and its late end changes nothing.
  std::this_thread::sleep_for(400ms);
  EXPECT_FALSE(store_->ClaimNext("daemon-b", 30.0));
  EXPECT_FALSE(store_->GetJob(e.job.id)) << "an expired preparation was not swept";
  EXPECT_THROW(store_->FinishPreparing(e.lease, e.job), LeaseLost);
}

TEST_P(StoreSuite, DeleteRemovesEverythingOfAFinishedJobOnly) {
  const std::int64_t id = store_->CreateJob(Job("d", 0, "k"), 100).job.id;
  const Lease lease = ClaimOne("d").lease;
  ProgressBatch b;
  b.trace.push_back(Row(0, 1.0));
  b.improvements.push_back({0, 0.0, 1.0, 1.0, 1, 1, Genome(12, 0)});
  b.checkpoint = "cp";
  b.checkpoint_generation = 0;
  store_->SaveProgress(lease, b);
  EXPECT_FALSE(store_->DeleteJob(id)) << "deleted a running job";
  store_->MarkFinished(lease, {JobState::kFailed, "boom", "", std::nullopt, 1.7e9, ""});
  EXPECT_EQ(store_->GetJob(id)->error, "boom");
  EXPECT_FALSE(store_->GetResult(id));
  EXPECT_TRUE(store_->DeleteJob(id));
  EXPECT_FALSE(store_->DeleteJob(id));
  EXPECT_FALSE(store_->GetJob(id));
  EXPECT_TRUE(store_->GetTrace(id, -1, 10).empty());
  EXPECT_TRUE(store_->GetImprovements(id).empty());
  EXPECT_FALSE(store_->GetCheckpoint(id));
  EXPECT_TRUE(store_->CreateJob(Job("d", 0, "k"), 100).created);  // the key is free again
}

// The one instantiation of StoreSuite for the whole program: every TEST_P of store_tests'
// files (store_*_test.cpp) runs on both stores, as Stores/StoreSuite.NAME/sqlite and
// /postgresql.
INSTANTIATE_TEST_SUITE_P(Stores, StoreSuite, ::testing::Values("sqlite", "postgresql"),
                         [](const auto& param_info) { return param_info.param; });

}  // namespace
}  // namespace springfit::server
