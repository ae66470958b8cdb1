// The store suite (store_suite_test.cpp) on damaged rows: quarantined once, by whichever read,
// listing or claim finds them, with the other jobs still listed and claimed.
#include <atomic>
#include <cstdint>
#include <future>
#include <map>
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

// A damaged row is its own error, naming the job and the value, never a job of another state
// or the client's fault. The row is quarantined, once: every later read names the same
// incident, listings show it apart, and the other jobs stay readable and listed.
TEST_P(StoreSuite, ADamagedRowIsQuarantinedOnceAndTheOthersStayListed) {
  const std::int64_t good = Create("good");
  const std::int64_t bogus = Create("bogus state");
  const std::int64_t garbled = Create("bad progress");
  const std::int64_t last = Create("last");
  factory_->ExecRaw("UPDATE jobs SET state = 'bogus' WHERE id = " + std::to_string(bogus));
  factory_->ExecRaw("UPDATE jobs SET progress = '{\"generation\": \"x\"' WHERE id = " +
                    std::to_string(garbled));
  const std::int64_t bogus_incident =
      CorruptIncident(bogus, "the store holds the unknown state 'bogus'");
  EXPECT_EQ(CorruptIncident(bogus, "is quarantined (quarantine incident"), bogus_incident);
  const std::int64_t garbled_incident = CorruptIncident(garbled, "progress column");
  EXPECT_NE(garbled_incident, bogus_incident);
  // A page at a time, the quarantined counted in the page: every job once, in order.
  JobFilter one;
  one.limit = 1;
  std::vector<std::int64_t> listed;
  std::map<std::int64_t, std::int64_t> incidents;
  std::map<std::int64_t, std::string> previous_states;
  for (int page = 0; page < 10; ++page) {
    const JobPage p = store_->ListJobs(one);
    for (const JobRecord& j : p.jobs) listed.push_back(j.id);
    for (const QuarantinedJob& q : p.quarantined) {
      listed.push_back(q.job_id);
      incidents[q.job_id] = q.incident;
      previous_states[q.job_id] = q.previous_state;
      EXPECT_NE(q.reason.find("job " + std::to_string(q.job_id)), std::string::npos) << q.reason;
    }
    if (!p.next_cursor) break;
    one.after_id = *p.next_cursor;
  }
  EXPECT_EQ(listed, (std::vector<std::int64_t>{good, bogus, garbled, last}));
  EXPECT_EQ(incidents, (std::map<std::int64_t, std::int64_t>{{bogus, bogus_incident},
                                                             {garbled, garbled_incident}}));
  // The state each had, to set back once repaired.
  EXPECT_EQ(previous_states,
            (std::map<std::int64_t, std::string>{{bogus, "bogus"}, {garbled, "queued"}}));
  ASSERT_TRUE(store_->GetJob(good));
  EXPECT_EQ(store_->GetJob(good)->state, JobState::kQueued);
  EXPECT_EQ(store_->CountQueued(), 2);
  // Another daemon of a shared store reads the same quarantine (and logs nothing).
  if (const std::unique_ptr<JobStore> second = factory_->Second()) {
    EXPECT_EQ(CorruptIncident(*second, garbled, "is quarantined"), garbled_incident);
    EXPECT_EQ(second->ListJobs(JobFilter{}).quarantined.size(), 2u);
  }
}

// Daemons (and threads) that find one damaged row at once quarantine it once: every read
// answers the same incident, none another error.
TEST_P(StoreSuite, ReadersFindingOneDamagedRowTogetherQuarantineItOnce) {
  const std::unique_ptr<JobStore> second = factory_->Second();
  std::vector<JobStore*> stores{store_.get()};
  if (second) stores.push_back(second.get());
  constexpr int kReaders = 6;
  for (int round = 0; round < 5; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    const std::int64_t id = Create("damaged");
    factory_->ExecRaw("UPDATE jobs SET progress = '{not json' WHERE id = " + std::to_string(id));
    std::atomic<int> ready{0};
    std::vector<std::future<std::int64_t>> reads;
    for (int r = 0; r < kReaders; ++r) {
      JobStore& store = *stores[r % stores.size()];
      reads.push_back(std::async(std::launch::async, [&store, &ready, id] {
        ++ready;
        while (ready.load() < kReaders) std::this_thread::yield();
        try {
          store.GetJob(id);
          return std::int64_t{-1};
        } catch (const StoreCorrupt& e) {
          return e.incident();
        }
      }));
    }
    std::set<std::int64_t> incidents;
    for (auto& read : reads) incidents.insert(read.get());
    ASSERT_EQ(incidents.size(), 1u);
    EXPECT_GT(*incidents.begin(), 0);
  }
}

// Damage found by a listing, before any read of the job: the whole listing answers, and the
// damaged job is quarantined by it. At a start, the unfinished jobs are read the same way.
TEST_P(StoreSuite, ListingsQuarantineDamageTheyFindAndGoOn) {
  const std::int64_t good = Create("good");
  const std::int64_t garbled = Create("bad progress");
  factory_->ExecRaw("UPDATE jobs SET progress = '{not json' WHERE id = " + std::to_string(garbled));
  const std::vector<JobRecord> unfinished = store_->UnfinishedJobs();
  ASSERT_EQ(unfinished.size(), 1u);
  EXPECT_EQ(unfinished[0].id, good);
  const JobPage page = store_->ListJobs(JobFilter{});
  ASSERT_EQ(page.jobs.size(), 1u);
  EXPECT_EQ(page.jobs[0].id, good);
  ASSERT_EQ(page.quarantined.size(), 1u);
  EXPECT_EQ(page.quarantined[0].job_id, garbled);
  EXPECT_GT(page.quarantined[0].incident, 0);
  EXPECT_EQ(CorruptIncident(garbled, "progress column"), page.quarantined[0].incident);
}

// A queued job whose row cannot be read is never claimed, not even once: it is quarantined by
// the claim that finds it, which takes the next job instead, so that one damaged row never
// holds up the queue (nor is handed out at every poll).
TEST_P(StoreSuite, AClaimQuarantinesADamagedRowAndTakesTheNextJob) {
  const std::int64_t damaged = Create("damaged", 5);
  const std::int64_t next = Create("next", 0);
  factory_->ExecRaw("UPDATE jobs SET progress = '{not json' WHERE id = " + std::to_string(damaged));
  std::optional<Claim> claim;
  ASSERT_NO_THROW(claim = store_->ClaimNext("d", 30.0));
  ASSERT_TRUE(claim);
  EXPECT_EQ(claim->job.id, next);
  EXPECT_EQ(claim->lease.epoch, 1);
  EXPECT_FALSE(store_->ClaimNext("d", 30.0)) << "the damaged job was handed out";
  EXPECT_GT(CorruptIncident(damaged, "progress column"), 0);
  EXPECT_EQ(store_->CountQueued(), 0);
  EXPECT_EQ(store_->RequestCancel(damaged), JobStore::CancelOutcome::kNotActive);
  // The claim that found it left it as it was (queued, to set back once repaired).
  const JobPage page = store_->ListJobs(JobFilter{});
  ASSERT_EQ(page.quarantined.size(), 1u);
  EXPECT_EQ(page.quarantined[0].previous_state, "queued");
}

}  // namespace
}  // namespace springfit::server
