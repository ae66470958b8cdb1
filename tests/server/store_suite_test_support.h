// The store suite's fixture (store_tests: store_*_test.cpp, postgres_store_test.cpp): the store
// under test, SQLite or a database of its own on the private PostgreSQL server that
// tests/server/with_postgres.sh starts (SPRINGFIT_TEST_PG_URL).
#pragma once
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

#include <SQLiteCpp/SQLiteCpp.h>
#include <gtest/gtest.h>
#include <pqxx/pqxx>

#include "server/store/job_store.h"
#include "server/store/postgres_store.h"
#include "server/store/sqlite_store.h"
#include "tests/server/store_test_data.h"

namespace springfit::server {

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

}  // namespace springfit::server
