// The store suite (store_suite_test.cpp) on claims and leases: the order of claims, the fence
// of an expired lease, renewals and releases, cancel requests, and concurrent claimers and
// submitters.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "server/store/job_store.h"
#include "tests/server/store_suite_test_support.h"

namespace springfit::server {
namespace {

using namespace std::chrono_literals;

TEST_P(StoreSuite, ClaimsComeByPriorityThenSubmissionOncePerJob) {
  Create("low", -1);
  Create("high", 5);
  Create("mid-1", 0);
  Create("mid-2", 0);
  std::vector<std::string> order;
  while (auto claim = store_->ClaimNext("daemon-a", 30.0)) {
    EXPECT_EQ(claim->job.state, JobState::kRunning);
    EXPECT_GT(claim->job.started_at, 1.7e9);
    EXPECT_EQ(claim->lease.epoch, 1);
    EXPECT_FALSE(claim->cancel_requested);
    order.push_back(claim->job.label);
  }
  EXPECT_EQ(order, (std::vector<std::string>{"high", "mid-1", "mid-2", "low"}));
  EXPECT_EQ(store_->CountQueued(), 0);
  EXPECT_EQ(store_->UnfinishedJobs().size(), 4u);  // running, leased
}

// The fence: once another daemon has claimed the job (the lease expired), every write of the
// old holder fails and changes nothing; the new holder's succeed.
TEST_P(StoreSuite, AnExpiredLeaseIsClaimedAgainAndItsOldHolderCannotWrite) {
  const std::int64_t id = Create("fenced");
  const Lease old_lease = ClaimOne("daemon-a", 0.2).lease;
  ProgressBatch before;
  before.trace.push_back(Row(0, 1.0));
  before.checkpoint = "cp-0";
  before.checkpoint_generation = 0;
  store_->SaveProgress(old_lease, before);
  EXPECT_FALSE(store_->ClaimNext("daemon-b", 30.0)) << "claimed while the lease held";
  std::this_thread::sleep_for(400ms);
  const Claim taken = ClaimOne("daemon-b");
  EXPECT_EQ(taken.job.id, id);
  EXPECT_EQ(taken.lease.epoch, old_lease.epoch + 1);
  EXPECT_EQ(taken.job.checkpoint_generation, 0);

  ProgressBatch late;
  late.trace.push_back(Row(1, 0.5));
  late.latest = late.trace.back();
  late.checkpoint = "cp-1-stale";
  late.checkpoint_generation = 1;
  EXPECT_THROW(store_->SaveProgress(old_lease, late), LeaseLost);
  EXPECT_THROW(store_->RewindTo(old_lease, -1), LeaseLost);
  EXPECT_THROW(store_->MarkFinished(old_lease, {JobState::kSucceeded, "", "{}", true, 2e9, ""}),
               LeaseLost);
  EXPECT_FALSE(store_->RenewLease(old_lease, 30.0).held);
  store_->ReleaseLease(old_lease);  // a no-op: not its lease
  EXPECT_FALSE(store_->ClaimNext("daemon-c", 30.0));
  // Nothing of the old holder's late writes is there.
  EXPECT_EQ(store_->GetTrace(id, -1, 10).size(), 1u);
  EXPECT_EQ(*store_->GetCheckpoint(id), "cp-0");
  EXPECT_EQ(store_->GetJob(id)->state, JobState::kRunning);

  store_->SaveProgress(taken.lease, late);
  store_->MarkFinished(taken.lease, {JobState::kSucceeded, "", "{}", true, 2e9, ""});
  EXPECT_EQ(store_->GetJob(id)->state, JobState::kSucceeded);
  // A finished job's lease is no one's.
  EXPECT_THROW(store_->SaveProgress(taken.lease, late), LeaseLost);
  EXPECT_FALSE(store_->RenewLease(taken.lease, 30.0).held);
}

TEST_P(StoreSuite, RenewedLeasesHoldAndReleasedOnesAreClaimedAtOnce) {
  Create("held");
  const Lease lease = ClaimOne("daemon-a", 0.3).lease;
  for (int i = 0; i < 6; ++i) {
    std::this_thread::sleep_for(100ms);
    EXPECT_TRUE(store_->RenewLease(lease, 0.3).held);
    EXPECT_FALSE(store_->ClaimNext("daemon-b", 30.0)) << "claimed a renewed lease";
  }
  store_->ReleaseLease(lease);
  const std::optional<Claim> taken = store_->ClaimNext("daemon-b", 30.0);
  ASSERT_TRUE(taken);
  EXPECT_EQ(taken->lease.epoch, 2);
  EXPECT_FALSE(store_->RenewLease(lease, 30.0).held);
}

// The lease history: every claim of a job, in the store's clock, with its renewals and how it
// ended (or that it lapsed), written with the lease; the claims follow each other; the old
// holder's late calls change none of it; it goes with its job.
TEST_P(StoreSuite, TheLeaseHistoryKeepsEveryClaimAndHowItEnded) {
  NewJob submitted = Job("history");
  submitted.preparing_owner = "daemon-p";
  const JobStore::Created created = store_->CreateJob(submitted, 10);
  const std::int64_t id = created.job.id;
  JobRecord prepared = created.job;
  store_->FinishPreparing(created.lease, prepared);
  const Lease lapsing = ClaimOne("daemon-a", 0.2).lease;
  const double renewed_from = store_->LeaseHistory(id).back().expires_at;
  EXPECT_TRUE(store_->RenewLease(lapsing, 0.3).held);
  std::this_thread::sleep_for(500ms);  // past the renewed lease: daemon-a froze
  const Lease released = ClaimOne("daemon-b").lease;
  EXPECT_FALSE(store_->RenewLease(lapsing, 30.0).held);
  store_->ReleaseLease(lapsing);  // a no-op: not its lease
  store_->ReleaseLease(released);
  const Lease finishing = ClaimOne("daemon-c").lease;
  store_->MarkFinished(finishing, {JobState::kSucceeded, "", "{}", true, 2e9, ""});

  const std::vector<LeaseRecord> history = store_->LeaseHistory(id);
  ASSERT_EQ(history.size(), 4u);
  const std::vector<std::string> owners = {"daemon-p", "daemon-a", "daemon-b", "daemon-c"};
  const std::vector<std::string> ended = {kLeasePrepared, "", kLeaseReleased, kLeaseFinished};
  for (std::size_t i = 0; i < history.size(); ++i) {
    SCOPED_TRACE("claim " + std::to_string(i + 1));
    EXPECT_EQ(history[i].epoch, static_cast<std::int64_t>(i + 1));
    EXPECT_EQ(history[i].owner, owners[i]);
    EXPECT_EQ(history[i].ended, ended[i]);
    EXPECT_EQ(history[i].ended_at.has_value(), !ended[i].empty());
    EXPECT_GT(history[i].granted_at, 1.7e9);
    EXPECT_GT(history[i].expires_at, history[i].granted_at);
    if (history[i].ended_at) {
      EXPECT_GE(*history[i].ended_at, history[i].granted_at);
    }
  }
  // daemon-a's renewal is in its record; it lapsed, and daemon-b's claim came after.
  EXPECT_GT(history[1].expires_at, renewed_from);
  EXPECT_GT(history[2].granted_at, history[1].expires_at);
  EXPECT_EQ(LeaseOverlap(history), std::nullopt);

  // A store that granted a claim while another held the job would say so.
  std::vector<LeaseRecord> overlapping = history;
  overlapping[2].granted_at = history[1].expires_at - 0.1;
  const std::optional<std::string> overlap = LeaseOverlap(overlapping);
  ASSERT_TRUE(overlap);
  EXPECT_NE(overlap->find("claim 3 by daemon-b"), std::string::npos) << *overlap;
  EXPECT_NE(overlap->find("claim 2 by daemon-a"), std::string::npos) << *overlap;
  overlapping = history;
  overlapping[3].granted_at = *history[2].ended_at - 0.1;  // before daemon-b handed it back
  ASSERT_TRUE(LeaseOverlap(overlapping));
  EXPECT_NE(LeaseOverlap(overlapping)->find("(released)"), std::string::npos);

  EXPECT_TRUE(store_->DeleteJob(id));
  EXPECT_TRUE(store_->LeaseHistory(id).empty());
}

TEST_P(StoreSuite, CancelsAreRequestsTheRunnersHeartbeatReads) {
  const std::int64_t queued = Create("queued", 0);
  const std::int64_t running = Create("running", 5);
  const Claim claim = ClaimOne("daemon-a", 0.2);
  ASSERT_EQ(claim.job.id, running);
  EXPECT_EQ(store_->RequestCancel(queued), JobStore::CancelOutcome::kCancelled);
  const auto cancelled = store_->GetJob(queued);
  EXPECT_EQ(cancelled->state, JobState::kCancelled);
  EXPECT_GT(cancelled->finished_at, 0.0);
  EXPECT_EQ(cancelled->started_at, 0.0);
  EXPECT_FALSE(store_->ClaimNext("daemon-b", 30.0)) << "a cancelled job was claimed";
  EXPECT_EQ(store_->RequestCancel(queued), JobStore::CancelOutcome::kNotActive);

  EXPECT_FALSE(store_->RenewLease(claim.lease, 0.2).cancel_requested);
  EXPECT_EQ(store_->RequestCancel(running), JobStore::CancelOutcome::kRequested);
  EXPECT_EQ(store_->GetJob(running)->state, JobState::kRunning);  // its runner ends it
  const LeaseStatus status = store_->RenewLease(claim.lease, 0.2);
  EXPECT_TRUE(status.held);
  EXPECT_TRUE(status.cancel_requested);
  // The runner died: the daemon that takes the job over learns of the cancel with its claim.
  std::this_thread::sleep_for(400ms);
  const Claim again = ClaimOne("daemon-b");
  EXPECT_TRUE(again.cancel_requested);
  store_->MarkFinished(again.lease, {JobState::kCancelled, "", "{}", std::nullopt, 2e9, ""});
  EXPECT_EQ(store_->RequestCancel(running), JobStore::CancelOutcome::kNotActive);
  EXPECT_EQ(store_->RequestCancel(12345), JobStore::CancelOutcome::kNotActive);
}

// Many claimers at once, on one store or (PostgreSQL) on two stores of one database: every
// job is claimed exactly once. Submitters racing the queue bound and one idempotency key:
// the bound holds and the key makes one job.
TEST_P(StoreSuite, ConcurrentClaimsAndSubmitsNeitherDuplicateNorOverflow) {
  constexpr int kJobs = 60;
  for (int i = 0; i < kJobs; ++i) Create("job-" + std::to_string(i));
  std::unique_ptr<JobStore> second = factory_->Second();
  JobStore& other = second ? *second : *store_;
  std::mutex mutex;
  std::vector<std::int64_t> claimed;
  std::vector<std::future<void>> claimers;
  for (int t = 0; t < 4; ++t) {
    claimers.push_back(std::async(std::launch::async, [&, t] {
      JobStore& store = t % 2 ? other : *store_;
      while (auto claim = store.ClaimNext("daemon-" + std::to_string(t), 30.0)) {
        std::lock_guard lock(mutex);
        claimed.push_back(claim->job.id);
      }
    }));
  }
  for (auto& f : claimers) f.get();
  std::sort(claimed.begin(), claimed.end());
  EXPECT_EQ(claimed.size(), static_cast<std::size_t>(kJobs));
  EXPECT_EQ(std::adjacent_find(claimed.begin(), claimed.end()), claimed.end())
      << "a job claimed twice";

  // Rounds of six submitters released at once against a bound one above the queue (on six
  // stores of one database with PostgreSQL): each round exactly one job gets in, and one
  // idempotency key submitted by all six makes one job.
  std::vector<std::unique_ptr<JobStore>> more;
  std::vector<JobStore*> submitters_stores;
  for (int t = 0; t < 6; ++t) {
    if (auto s = factory_->Second()) more.push_back(std::move(s));
    submitters_stores.push_back(more.empty() ? store_.get() : more.back().get());
  }
  for (int round = 0; round < 15; ++round) {
    const int bound = store_->CountQueued() + 1;
    std::atomic<int> ready{0};
    std::atomic<int> created{0};
    std::set<std::int64_t> keyed;
    std::vector<std::future<void>> submitters;
    for (JobStore* store : submitters_stores) {
      submitters.push_back(std::async(std::launch::async, [&, store] {
        ++ready;
        while (ready.load() < 6) std::this_thread::yield();
        if (store->CreateJob(Job("bounded"), bound).created) ++created;
        const auto k = store->CreateJob(Job("keyed", 0, "key-" + std::to_string(round)), 100000);
        std::lock_guard lock(mutex);
        keyed.insert(k.job.id);
      }));
    }
    for (auto& f : submitters) f.get();
    EXPECT_EQ(created.load(), 1) << "round " << round << ": the bound " << bound << " overflowed";
    EXPECT_EQ(keyed.size(), 1u) << "round " << round << ": one key made several jobs";
  }
}

}  // namespace
}  // namespace springfit::server
