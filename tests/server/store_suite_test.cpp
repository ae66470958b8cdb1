// One suite, two stores: every behaviour the daemons rely on (server/store/job_store.h), run
// against the embedded SQLite store and against a real PostgreSQL server. The PostgreSQL
// half needs SPRINGFIT_TEST_PG_URL, the URL of a private server that
// tests/server/with_postgres.sh starts around this program; without it those tests fail,
// naming the script, rather than skip.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <SQLiteCpp/SQLiteCpp.h>
#include <gtest/gtest.h>
#include <pqxx/pqxx>

#include "proto/outcome_codec.h"
#include "proto/scene_codec.h"
#include "server/jobs/scheduler.h"
#include "server/store/forwarding_store.h"
#include "server/store/postgres_store.h"
#include "server/store/sqlite_store.h"
#include "tests/server/store_test_data.h"
#include "tests/test_scenes.h"

namespace springfit::server {
namespace {

using namespace std::chrono_literals;

// Opens the store under test; `Second()` opens another store on the same database (a second
// daemon), or returns null where one database has one daemon (SQLite).
class StoreFactory {
 public:
  virtual ~StoreFactory() = default;
  virtual std::unique_ptr<JobStore> Open() = 0;
  virtual std::unique_ptr<JobStore> Second() = 0;
  // Runs SQL on the database behind the store's back (damage for the tests).
  virtual void ExecRaw(const std::string& sql) = 0;
};

class SqliteFactory final : public StoreFactory {
 public:
  explicit SqliteFactory(std::string path) : path_(std::move(path)) {}
  std::unique_ptr<JobStore> Open() override { return std::make_unique<SqliteStore>(path_); }
  std::unique_ptr<JobStore> Second() override { return nullptr; }
  void ExecRaw(const std::string& sql) override {
    SQLite::Database db(path_, SQLite::OPEN_READWRITE);
    db.exec(sql);
  }

 private:
  std::string path_;
};

// A new database on the private server for each test.
class PostgresFactory final : public StoreFactory {
 public:
  explicit PostgresFactory(const std::string& name) {
    const char* admin = std::getenv("SPRINGFIT_TEST_PG_URL");
    if (!admin || !*admin) {
      throw std::runtime_error(
          "SPRINGFIT_TEST_PG_URL is not set: run this suite through "
          "tests/server/with_postgres.sh (PostgreSQL from scripts/install-deps.sh)");
    }
    pqxx::connection c(admin);
    pqxx::nontransaction w(c);
    w.exec("DROP DATABASE IF EXISTS " + name);
    w.exec("CREATE DATABASE " + name);
    const std::string base = admin;
    const std::size_t query = base.find('?');
    const std::size_t slash = base.rfind('/', query);
    url_ =
        base.substr(0, slash + 1) + name + (query == std::string::npos ? "" : base.substr(query));
  }
  std::unique_ptr<JobStore> Open() override { return std::make_unique<PostgresStore>(url_, ""); }
  std::unique_ptr<JobStore> Second() override { return Open(); }
  const std::string& url() const { return url_; }
  void ExecRaw(const std::string& sql) override {
    pqxx::connection c(url_);
    pqxx::nontransaction w(c);
    w.exec(sql);
  }

 private:
  std::string url_;
};

class StoreSuite : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = std::filesystem::temp_directory_path() /
           ("springfit-suite-" + std::to_string(::getpid()) + "-" + info->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    if (GetParam() == "sqlite") {
      factory_ = std::make_unique<SqliteFactory>((dir_ / "jobs.db").string());
    } else {
      std::string name = "t_" + std::string(info->name());
      name = name.substr(0, name.find('/'));
      std::transform(name.begin(), name.end(), name.begin(),
                     [](unsigned char c) { return std::isalnum(c) ? std::tolower(c) : '_'; });
      factory_ = std::make_unique<PostgresFactory>(name.substr(0, 60));
    }
    store_ = factory_->Open();
  }
  void TearDown() override {
    store_.reset();
    std::filesystem::remove_all(dir_);
  }

  static NewJob Job(const std::string& label, int priority = 0, const std::string& key = "") {
    return StoreTestJob(label, priority, key);
  }
  static TraceRow Row(int generation, double error) { return StoreTestRow(generation, error); }

  std::int64_t Create(const std::string& label, int priority = 0) {
    return store_->CreateJob(Job(label, priority), 1000).job.id;
  }

  // The incident of the StoreCorrupt that reading job `id` throws, whose message must hold
  // `what`; 0 (a failure) when the read succeeds.
  std::int64_t CorruptIncident(std::int64_t id, const std::string& what) {
    return CorruptIncident(*store_, id, what);
  }
  static std::int64_t CorruptIncident(JobStore& store, std::int64_t id, const std::string& what) {
    try {
      store.GetJob(id);
      ADD_FAILURE() << "job " << id << ": a damaged row was read";
    } catch (const StoreCorrupt& e) {
      EXPECT_NE(std::string(e.what()).find("job " + std::to_string(id)), std::string::npos)
          << e.what();
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
      EXPECT_GT(e.incident(), 0) << e.what();
      return e.incident();
    }
    return 0;
  }

  // Claims the one job there is, for `owner`.
  Claim ClaimOne(const std::string& owner, double lease_seconds = 30.0) {
    std::optional<Claim> claim = store_->ClaimNext(owner, lease_seconds);
    if (!claim) throw std::runtime_error("nothing to claim");
    return *claim;
  }

  std::filesystem::path dir_;
  std::unique_ptr<StoreFactory> factory_;
  std::unique_ptr<JobStore> store_;
};

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

INSTANTIATE_TEST_SUITE_P(Stores, StoreSuite, ::testing::Values("sqlite", "postgresql"),
                         [](const auto& param_info) { return param_info.param; });

// PostgreSQL alone: a change made through one daemon's store wakes the others' listeners.
TEST(PostgresStoreOnly, AJobSubmittedThroughOneStoreWakesTheOthers) {
  PostgresFactory factory("t_wakeup");
  std::unique_ptr<JobStore> a = factory.Open();
  std::unique_ptr<JobStore> b = factory.Second();
  std::atomic<int> wakes{0};
  b->SetChangeListener([&] { ++wakes; });
  std::this_thread::sleep_for(300ms);  // its LISTEN is in place
  const int before = wakes.load();
  a->CreateJob(NewJob{[] {
                        JobRecord r;
                        r.label = "x";
                        r.scene_name = "s";
                        r.strategy = "paper";
                        return r;
                      }(),
                      "{}", "", 10.0},
               10);
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (wakes.load() == before && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(10ms);
  EXPECT_GT(wakes.load(), before) << "no wake-up within 5 s";
}

// PostgreSQL alone: daemons starting together on a new database migrate it once (under the
// advisory lock); none fails on a table another created.
TEST(PostgresStoreOnly, DaemonsStartingTogetherMigrateOnce) {
  PostgresFactory factory("t_migrate_together");
  std::vector<std::future<int>> opens;
  std::atomic<int> ready{0};
  for (int i = 0; i < 4; ++i) {
    opens.push_back(std::async(std::launch::async, [&] {
      ++ready;
      while (ready.load() < 4) std::this_thread::yield();
      auto store = factory.Open();
      return static_cast<PostgresStore&>(*store).schema_version();
    }));
  }
  for (auto& f : opens) EXPECT_EQ(f.get(), PostgresStore::kSchemaVersion);
}

// PostgreSQL alone: a call whose deadline passes after its last round trip succeeds, and the
// watchdog shuts its socket all the same. The next call on that connection (the writer's, here
// a progress write; a reader's) must not fail on the dead socket: the connection is replaced.
TEST(PostgresStoreOnly, AWatchdogFiringAfterASuccessfulCallLeavesNoDeadConnection) {
  PostgresFactory factory("t_late_watchdog");
  std::atomic<bool> linger{false};
  PostgresStore::Options options;
  options.call_seconds = 1.0;
  options.readers = 1;
  // The call has answered; its end comes after the deadline (and the watchdog's 50 ms beat).
  options.on_call_end = [&] {
    if (linger.exchange(false)) std::this_thread::sleep_for(1500ms);
  };
  PostgresStore store(factory.url(), "", options);
  const std::int64_t id = store.CreateJob(StoreTestJob("late"), 10).job.id;
  const std::optional<Claim> claim = store.ClaimNext("d", 30.0);
  ASSERT_TRUE(claim);
  linger = true;
  EXPECT_TRUE(store.RenewLease(claim->lease, 30.0).held);
  ProgressBatch batch;
  batch.latest = StoreTestRow(1, 0.5);
  EXPECT_NO_THROW(store.SaveProgress(claim->lease, batch));
  linger = true;
  EXPECT_TRUE(store.GetJob(id));
  try {
    const std::optional<JobRecord> job = store.GetJob(id);
    ASSERT_TRUE(job && job->progress);
    EXPECT_EQ(job->progress->generation, 1);
  } catch (const StoreUnavailable& e) {
    ADD_FAILURE() << "the reader kept the connection the watchdog shut: " << e.what();
  }
}

// PostgreSQL alone: a read takes a reading connection no call holds. One read held on its
// connection (a slow query) must not delay the others, which the other connection serves
// within server.info's kind of deadline.
TEST(PostgresStoreOnly, AReadTakesAFreeConnectionWhileAnotherIsHeld) {
  PostgresFactory factory("t_free_reader");
  std::atomic<bool> hold_next{false};
  std::atomic<bool> holding{false};
  std::atomic<bool> release{false};
  PostgresStore::Options options;
  options.readers = 2;
  // The next call to end holds its connection until released (its thread: the slow read's).
  options.on_call_end = [&] {
    if (!hold_next.exchange(false)) return;
    holding = true;
    while (!release.load()) std::this_thread::sleep_for(5ms);
  };
  PostgresStore store(factory.url(), "", options);
  const std::int64_t id = store.CreateJob(StoreTestJob("read"), 10).job.id;
  hold_next = true;
  auto slow = std::async(std::launch::async, [&] { return store.GetJob(id).has_value(); });
  // (Released however the test ends: `slow` waits for its thread.)
  const std::shared_ptr<void> release_at_end(nullptr, [&](void*) { release = true; });
  const auto deadline = std::chrono::steady_clock::now() + 30s;
  while (!holding.load() && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(5ms);
  ASSERT_TRUE(holding.load()) << "the slow read did not start";
  for (int i = 0; i < 6; ++i) {
    SCOPED_TRACE("read " + std::to_string(i));
    const ScopedStoreDeadline within(1.0);
    const auto start = std::chrono::steady_clock::now();
    EXPECT_NO_THROW(EXPECT_TRUE(store.GetJob(id)));
    EXPECT_NO_THROW(EXPECT_EQ(store.CountQueued(), 1));
    EXPECT_LT(std::chrono::steady_clock::now() - start, 1s);
  }
  release = true;
  EXPECT_TRUE(slow.get());
}

}  // namespace
}  // namespace springfit::server
