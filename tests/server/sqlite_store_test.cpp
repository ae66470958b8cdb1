#include "server/sqlite_store.h"

#include <filesystem>

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
    NewJob j;
    j.record.label = label;
    j.record.priority = priority;
    j.record.seed = 0xfedcba9876543210ULL;  // above int64's range: stored as its bits
    j.record.idempotency_key = key;
    j.record.scene_name = "s";
    j.record.genes = 12;
    j.record.strategy = "default";
    j.record.max_generations = 100;
    j.record.created_at = 1.5e9;
    j.scene_json = R"({"name":"s"})";
    return j;
  }

  static TraceRow Row(int generation, double error) {
    TraceRow r;
    r.generation = generation;
    r.evaluations = 10 * (generation + 1);
    r.best_cost = error * 2;
    r.best_normalized_error = error;
    r.missing = generation == 0 ? -1 : 3;
    r.extra = 1;
    return r;
  }

  std::filesystem::path dir_;
  std::string path_;
};

TEST_F(SqliteStoreTest, CreateGetAndIdempotencyKeys) {
  SqliteStore store(path_);
  EXPECT_EQ(store.schema_version(), SqliteStore::kSchemaVersion);
  const auto a = store.CreateJob(Job("a", 0, "key-1"));
  EXPECT_TRUE(a.created);
  EXPECT_EQ(a.job.state, JobState::kQueued);
  const auto again = store.CreateJob(Job("different label", 5, "key-1"));
  EXPECT_FALSE(again.created);
  EXPECT_EQ(again.job.id, a.job.id);
  EXPECT_EQ(again.job.label, "a");
  const auto b = store.CreateJob(Job("b"));
  const auto c = store.CreateJob(Job("c"));  // no key: never deduplicated
  EXPECT_NE(b.job.id, c.job.id);
  const auto got = store.GetJob(a.job.id);
  ASSERT_TRUE(got);
  EXPECT_EQ(got->seed, 0xfedcba9876543210ULL);
  EXPECT_EQ(got->idempotency_key, "key-1");
  EXPECT_EQ(*store.GetScene(a.job.id), R"({"name":"s"})");
  EXPECT_FALSE(store.GetJob(999));
  EXPECT_EQ(store.CountQueued(), 3);
}

TEST_F(SqliteStoreTest, ListPagesAndFilters) {
  SqliteStore store(path_);
  for (int i = 0; i < 7; ++i) store.CreateJob(Job(i % 2 ? "odd" : "even"));
  store.MarkFinished(1, JobState::kSucceeded, "", "{}", true, 2e9);
  JobFilter f;
  f.limit = 3;
  std::vector<std::int64_t> ids;
  for (int page = 0; page < 10; ++page) {
    const JobPage p = store.ListJobs(f);
    for (const auto& j : p.jobs) ids.push_back(j.id);
    if (!p.next_cursor) break;
    f.after_id = *p.next_cursor;
  }
  EXPECT_EQ(ids, (std::vector<std::int64_t>{1, 2, 3, 4, 5, 6, 7}));
  JobFilter odd;
  odd.label = "odd";
  EXPECT_EQ(store.ListJobs(odd).jobs.size(), 3u);
  JobFilter done;
  done.state = JobState::kSucceeded;
  const JobPage finished = store.ListJobs(done);
  ASSERT_EQ(finished.jobs.size(), 1u);
  EXPECT_EQ(finished.jobs[0].exact, std::optional<bool>(true));
  EXPECT_FALSE(finished.next_cursor);
}

TEST_F(SqliteStoreTest, UnfinishedJobsComeByPriorityThenSubmission) {
  SqliteStore store(path_);
  store.CreateJob(Job("low", -1));
  store.CreateJob(Job("high", 5));
  store.CreateJob(Job("mid-1", 0));
  store.CreateJob(Job("mid-2", 0));
  store.MarkRunning(4, 1.6e9);
  std::vector<std::string> order;
  for (const auto& j : store.UnfinishedJobs()) order.push_back(j.label);
  EXPECT_EQ(order, (std::vector<std::string>{"high", "mid-1", "mid-2", "low"}));
}

TEST_F(SqliteStoreTest, ProgressCheckpointRewindAndFinish) {
  SqliteStore store(path_);
  const std::int64_t id = store.CreateJob(Job("p")).job.id;
  store.MarkRunning(id, 1.6e9);
  ProgressBatch first;
  for (int g = 0; g <= 4; ++g) first.trace.push_back(Row(g, 1.0 / (g + 1)));
  first.improvements.push_back(
      {0, 0.1, 2.0, 1.0, -1, 1, Genome{1, 0, 1, 1, 0, 0, 0, 0, 1, 1, 1, 0}});
  first.latest = first.trace.back();
  first.checkpoint = std::string("state\0with\0zeros", 16);
  first.checkpoint_generation = 4;
  store.SaveProgress(id, first);
  ProgressBatch second;
  for (int g = 5; g <= 6; ++g) second.trace.push_back(Row(g, 0.1));
  second.improvements.push_back({5, 0.5, 0.2, 0.1, 3, 1, Genome(12, 1)});
  second.latest = second.trace.back();
  store.SaveProgress(id, second);

  const auto job = store.GetJob(id);
  EXPECT_EQ(job->state, JobState::kRunning);
  EXPECT_EQ(job->checkpoint_generation, 4);
  ASSERT_TRUE(job->progress);
  EXPECT_EQ(job->progress->generation, 6);
  EXPECT_EQ(*store.GetCheckpoint(id), std::string("state\0with\0zeros", 16));
  EXPECT_EQ(store.GetTrace(id, -1, 100).size(), 7u);
  const auto page = store.GetTrace(id, 2, 2);
  ASSERT_EQ(page.size(), 2u);
  EXPECT_EQ(page[0].generation, 3);
  EXPECT_TRUE(page[0].SameSearch(Row(3, 0.25)));
  EXPECT_EQ(store.GetTrace(id, -1, 1)[0].missing, -1);  // null stays unknown

  // Resuming from the checkpoint at 4 drops what came after it.
  store.RewindTo(id, 4);
  EXPECT_EQ(store.GetTrace(id, -1, 100).size(), 5u);
  const auto improvements = store.GetImprovements(id);
  ASSERT_EQ(improvements.size(), 1u);
  EXPECT_EQ(improvements[0].genome, (Genome{1, 0, 1, 1, 0, 0, 0, 0, 1, 1, 1, 0}));

  store.MarkFinished(id, JobState::kSucceeded, "", R"({"cost":0})", false, 1.7e9);
  EXPECT_FALSE(store.GetCheckpoint(id));  // a finished job never resumes
  EXPECT_EQ(*store.GetResult(id), R"({"cost":0})");
  EXPECT_EQ(store.GetJob(id)->exact, std::optional<bool>(false));
  EXPECT_TRUE(store.UnfinishedJobs().empty());
}

TEST_F(SqliteStoreTest, DeleteRemovesEverythingOfTheJob) {
  SqliteStore store(path_);
  const std::int64_t id = store.CreateJob(Job("d", 0, "k")).job.id;
  ProgressBatch b;
  b.trace.push_back(Row(0, 1.0));
  b.improvements.push_back({0, 0.0, 1.0, 1.0, 1, 1, Genome(12, 0)});
  store.SaveProgress(id, b);
  store.MarkFinished(id, JobState::kFailed, "boom", "", std::nullopt, 1.7e9);
  EXPECT_EQ(store.GetJob(id)->error, "boom");
  EXPECT_TRUE(store.DeleteJob(id));
  EXPECT_FALSE(store.DeleteJob(id));
  EXPECT_FALSE(store.GetJob(id));
  EXPECT_TRUE(store.GetTrace(id, -1, 10).empty());
  EXPECT_TRUE(store.GetImprovements(id).empty());
  EXPECT_TRUE(store.CreateJob(Job("d", 0, "k")).created);  // the key is free again
}

TEST_F(SqliteStoreTest, DataSurvivesReopening) {
  std::int64_t id = 0;
  {
    SqliteStore store(path_);
    id = store.CreateJob(Job("kept")).job.id;
    ProgressBatch b;
    b.trace.push_back(Row(0, 0.5));
    b.checkpoint = "cp";
    b.checkpoint_generation = 0;
    store.SaveProgress(id, b);
  }
  SqliteStore reopened(path_);
  EXPECT_EQ(reopened.GetJob(id)->label, "kept");
  EXPECT_EQ(reopened.GetTrace(id, -1, 10).size(), 1u);
  EXPECT_EQ(*reopened.GetCheckpoint(id), "cp");
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
