#include "server/store/sqlite_store.h"

#include "tests/server/power_loss_vfs.h"
#include "tests/server/store_test_data.h"

#include <chrono>
#include <filesystem>
#include <fstream>
#include <future>
#include <thread>

#include <SQLiteCpp/SQLiteCpp.h>
#include <gtest/gtest.h>

namespace springfit::server {
namespace {

class SqliteStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("springfit-store-" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
            "-" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    path_ = (dir_ / "jobs.db").string();
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  static NewJob Job(const std::string& label, int priority = 0, const std::string& key = "") {
    return StoreTestJob(label, priority, key);
  }
  static TraceRow Row(int generation, double error) { return StoreTestRow(generation, error); }

  std::filesystem::path dir_;
  std::string path_;
};

// What only the embedded store does; the behaviour both stores share is in
// store_suite_test.cpp.

TEST_F(SqliteStoreTest, DataSurvivesReopeningAndADeadDaemonsLeasesAreFreed) {
  std::int64_t id = 0;
  std::int64_t lapsed = 0;
  Lease lease;
  {
    SqliteStore store(path_);
    EXPECT_EQ(store.schema_version(), SqliteStore::kSchemaVersion);
    EXPECT_EQ(store.Describe(), "sqlite:///" + path_);
    id = store.CreateJob(Job("kept"), 10).job.id;
    lapsed = store.CreateJob(Job("lapsed"), 10).job.id;
    lease = store.ClaimNext("crashed-daemon", 3600.0)->lease;
    // A claim that lapsed and was claimed again before the crash: the crash ends the second.
    EXPECT_EQ(store.ClaimNext("crashed-daemon", 0.05)->job.id, lapsed);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    EXPECT_EQ(store.ClaimNext("crashed-daemon", 3600.0)->lease.epoch, 2);
    ProgressBatch b;
    b.trace.push_back(Row(0, 0.5));
    b.checkpoint = "cp";
    b.checkpoint_generation = 0;
    store.SaveProgress(lease, b);
  }
  // The next daemon on the file holds its lock: the hour-long lease is a dead daemon's, and
  // the job is claimed at once.
  SqliteStore reopened(path_);
  EXPECT_EQ(reopened.GetJob(id)->label, "kept");
  EXPECT_EQ(reopened.GetTrace(id, -1, 10).size(), 1u);
  EXPECT_EQ(*reopened.GetCheckpoint(id), "cp");
  const std::optional<Claim> claim = reopened.ClaimNext("next-daemon", 10.0);
  ASSERT_TRUE(claim);
  EXPECT_EQ(claim->job.id, id);
  EXPECT_EQ(claim->lease.epoch, lease.epoch + 1);
  EXPECT_THROW(reopened.SaveProgress(lease, ProgressBatch{}), LeaseLost);
  // Its lease history says the dead daemon's claim ended when the next one opened the file,
  // before the hour was out, and the new claim began after that.
  const std::vector<LeaseRecord> history = reopened.LeaseHistory(id);
  ASSERT_EQ(history.size(), 2u);
  EXPECT_EQ(history[0].owner, "crashed-daemon");
  EXPECT_EQ(history[0].ended, kLeaseHolderGone);
  ASSERT_TRUE(history[0].ended_at);
  EXPECT_LT(*history[0].ended_at, history[0].expires_at);
  EXPECT_EQ(history[1].owner, "next-daemon");
  EXPECT_EQ(LeaseOverlap(history), std::nullopt);
  const std::vector<LeaseRecord> again = reopened.LeaseHistory(lapsed);
  ASSERT_EQ(again.size(), 2u);
  EXPECT_EQ(again[0].ended, "") << "a lapsed claim ended by a crash after it";
  EXPECT_EQ(again[1].ended, kLeaseHolderGone);
  EXPECT_EQ(LeaseOverlap(again), std::nullopt);
}

// A power cut: what SQLite did not sync is lost (power_loss_vfs.h). Every write the store
// acknowledged (a submission answered, progress and a checkpoint saved, a cancel, a result)
// was synced before it returned, so all of it is there after the cut; the store, closed by
// the dying process, writes nothing more. (With `PRAGMA synchronous = NORMAL` the WAL is
// synced only at checkpoints, and every job here is lost.)
TEST_F(SqliteStoreTest, EveryAcknowledgedWriteSurvivesAPowerCut) {
  testing::PowerLossVfs vfs;
  std::vector<std::int64_t> ids;
  Lease running;
  std::int64_t finished = 0;
  std::int64_t cancelled = 0;
  {
    SqliteStore store(path_);
    for (int i = 0; i < 20; ++i)
      ids.push_back(store.CreateJob(Job("job-" + std::to_string(i)), 1000).job.id);
    running = store.ClaimNext("daemon-a", 30.0)->lease;
    ProgressBatch batch;
    for (int g = 0; g < 5; ++g) batch.trace.push_back(Row(g, 1.0 / (g + 1)));
    batch.latest = batch.trace.back();
    batch.checkpoint = "checkpoint at 4";
    batch.checkpoint_generation = 4;
    store.SaveProgress(running, batch);
    cancelled = ids[1];
    ASSERT_EQ(store.RequestCancel(cancelled), JobStore::CancelOutcome::kCancelled);
    const Claim second = *store.ClaimNext("daemon-a", 30.0);
    finished = second.job.id;
    store.MarkFinished(second.lease,
                       {JobState::kSucceeded, "", R"({"stop":"target"})", true, 2e9, ""});
    EXPECT_GT(vfs.Syncs("-wal"), 0) << "nothing was synced: the VFS is not in use";
    vfs.Cut();
  }  // (its connections close as the process dies: their last checkpoint reaches nothing)
  vfs.Restore();

  SqliteStore store(path_);
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const std::optional<JobRecord> job = store.GetJob(ids[i]);
    ASSERT_TRUE(job) << "acknowledged job " << ids[i] << " lost in the power cut";
    EXPECT_EQ(job->label, "job-" + std::to_string(i));
  }
  EXPECT_EQ(store.GetJob(running.job_id)->state, JobState::kRunning);
  EXPECT_EQ(store.GetTrace(running.job_id, -1, 100).size(), 5u);
  EXPECT_EQ(store.GetCheckpoint(running.job_id), std::optional<std::string>("checkpoint at 4"));
  EXPECT_EQ(store.GetJob(cancelled)->state, JobState::kCancelled);
  EXPECT_EQ(store.GetJob(finished)->state, JobState::kSucceeded);
  EXPECT_EQ(store.GetResult(finished), std::optional<std::string>(R"({"stop":"target"})"));
  // The job that was running resumes, from its checkpoint, at the first claim.
  const std::optional<Claim> resumed = store.ClaimNext("daemon-b", 30.0);
  ASSERT_TRUE(resumed);
  EXPECT_EQ(resumed->job.id, running.job_id);
  EXPECT_EQ(resumed->job.checkpoint_generation, 4);
}

// Reads go to the reader connections: a write waiting for the file's write lock (held here by
// another connection, as a checkpoint or a backup would) holds the writer, not job.get.
TEST_F(SqliteStoreTest, ReadsDoNotWaitBehindAWriteInProgress) {
  SqliteStore store(path_);
  const std::int64_t id = store.CreateJob(Job("existing"), 10).job.id;
  SQLite::Database other(path_, SQLite::OPEN_READWRITE);
  other.exec("BEGIN IMMEDIATE");  // the write lock, until the rollback below
  std::future<JobStore::Created> write =
      std::async(std::launch::async, [&] { return store.CreateJob(Job("waiting"), 10); });
  // Let the write take the writer and wait for the lock (SQLite's busy timeout is 5 s).
  EXPECT_EQ(write.wait_for(std::chrono::milliseconds(300)), std::future_status::timeout);
  std::future<std::optional<JobRecord>> read =
      std::async(std::launch::async, [&] { return store.GetJob(id); });
  const bool read_first = read.wait_for(std::chrono::seconds(3)) == std::future_status::ready &&
                          write.wait_for(std::chrono::seconds(0)) == std::future_status::timeout;
  other.exec("ROLLBACK");
  EXPECT_TRUE(read_first) << "job.get waited for the write in progress";
  ASSERT_TRUE(read.get());
  EXPECT_TRUE(write.get().created);
  // The reader sees what the writer committed.
  EXPECT_EQ(store.ListJobs(JobFilter{}).jobs.size(), 2u);
}

TEST_F(SqliteStoreTest, ASecondDaemonOnTheSameDatabaseIsRefused) {
  SqliteStore first(path_);
  try {
    SqliteStore second(path_);
    FAIL() << "two stores opened one database";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("in use by another springfitd"), std::string::npos)
        << e.what();
  }
  first.CreateJob(Job("still fine"), 10);  // the refused one changed nothing
  EXPECT_EQ(first.CountQueued(), 1);
}

TEST_F(SqliteStoreTest, ADatabaseInAMissingDirectoryIsRefusedByName) {
  const std::string path = (dir_ / "missing" / "jobs.db").string();
  try {
    SqliteStore store(path);
    FAIL() << "a store opened in a missing directory";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()),
              "cannot create the database " + path + ": No such file or directory");
  }
}

// Damage where opening the store reads nothing (the trace's pages at the end of the file):
// only the check at the start finds it, before any job trips over it.
TEST_F(SqliteStoreTest, ADamagedDatabaseIsRefusedAtTheStart) {
  {
    SqliteStore store(path_);
    store.CreateJob(Job("traced"), 10);
    const Lease lease = store.ClaimNext("d", 60.0)->lease;
    ProgressBatch b;
    for (int g = 0; g < 5000; ++g) b.trace.push_back(Row(g, 1.0 / (g + 1)));
    store.SaveProgress(lease, b);
  }
  const auto size = static_cast<std::streamoff>(std::filesystem::file_size(path_));
  ASSERT_GT(size, 20 * 4096);
  {
    // Pages overwritten, as a failing disk would leave them.
    std::fstream f(path_, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(size - 4 * 4096);
    const std::string garbage(2 * 4096, '\xa5');
    f.write(garbage.data(), static_cast<std::streamsize>(garbage.size()));
  }
  try {
    SqliteStore store(path_);
    FAIL() << "opened a damaged database";
  } catch (const std::runtime_error& e) {
    const std::string why = e.what();
    EXPECT_NE(why.find(path_), std::string::npos) << why;
    EXPECT_NE(why.find("is damaged"), std::string::npos) << why;
  }
}

// The jobs table of version 1 (the other tables are untouched by the migration to 2).
TEST_F(SqliteStoreTest, MigratesAVersion1Database) {
  {
    SQLite::Database db(path_, SQLite::OPEN_READWRITE | SQLite::OPEN_CREATE);
    db.exec(
        "CREATE TABLE jobs (id INTEGER PRIMARY KEY AUTOINCREMENT, label TEXT NOT NULL, priority "
        "INTEGER NOT NULL, seed INTEGER NOT NULL, idempotency_key TEXT UNIQUE, state TEXT NOT "
        "NULL, error TEXT NOT NULL DEFAULT '', scene_name TEXT NOT NULL, genes INTEGER NOT NULL, "
        "strategy TEXT NOT NULL, max_generations INTEGER NOT NULL, created_at REAL NOT NULL, "
        "started_at REAL NOT NULL DEFAULT 0, finished_at REAL NOT NULL DEFAULT 0, progress TEXT, "
        "checkpoint_generation INTEGER NOT NULL DEFAULT -1, exact INTEGER, scene TEXT NOT NULL, "
        "result TEXT)");
    db.exec(
        "INSERT INTO jobs (label, priority, seed, state, scene_name, genes, strategy, "
        "max_generations, created_at, started_at, scene) VALUES ('old', 0, 1, 'running', 's', "
        "12, 'paper', 10, 1.5e9, 1.6e9, '{}')");
    db.exec("PRAGMA user_version = 1");
  }
  // Version 2 adds the lease columns: the job a version-1 daemon left running is claimed.
  SqliteStore store(path_);
  EXPECT_EQ(store.schema_version(), SqliteStore::kSchemaVersion);
  const std::optional<Claim> claim = store.ClaimNext("upgraded", 10.0);
  ASSERT_TRUE(claim);
  EXPECT_EQ(claim->job.label, "old");
  EXPECT_EQ(claim->job.started_at, 1.6e9);  // kept from its first start
  EXPECT_EQ(claim->lease.epoch, 1);
  EXPECT_FALSE(claim->cancel_requested);
}

TEST_F(SqliteStoreTest, RefusesADatabaseOfANewerSchema) {
  { SqliteStore store(path_); }
  {
    SQLite::Database db(path_, SQLite::OPEN_READWRITE);
    db.exec("PRAGMA user_version = " + std::to_string(SqliteStore::kSchemaVersion + 1));
  }
  try {
    SqliteStore store(path_);
    FAIL() << "opened a newer schema";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("newer"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace springfit::server
