// The embedded store: one SQLite database file in WAL mode (server/job_store.h).
//
// One connection behind a mutex: the daemon's writes are small and batched (a job flushes
// its progress about once a second), so a single writer is never the bottleneck, and WAL
// lets readers of the same file (sqlite3 on the command line, a backup) work alongside.
// synchronous=FULL: a flushed batch survives a power cut, not only a crash of the daemon.
//
// The schema's version is PRAGMA user_version; opening a database migrates it to the
// current version in one transaction, and refuses a database of a newer springfit.
#pragma once
#include <memory>
#include <mutex>
#include <string>

#include "server/job_store.h"

namespace SQLite {
class Database;
}

namespace springfit::server {

class SqliteStore final : public JobStore {
 public:
  static constexpr int kSchemaVersion = 1;

  // Opens or creates the database; throws std::runtime_error with the reason.
  explicit SqliteStore(const std::string& path);
  ~SqliteStore() override;

  Created CreateJob(const NewJob& job) override;
  std::optional<JobRecord> GetJob(std::int64_t id) override;
  std::optional<std::string> GetScene(std::int64_t id) override;
  JobPage ListJobs(const JobFilter& filter) override;
  std::vector<JobRecord> UnfinishedJobs() override;
  int CountQueued() override;
  void MarkRunning(std::int64_t id, double started_at) override;
  void SaveProgress(std::int64_t id, const ProgressBatch& batch) override;
  void MarkFinished(std::int64_t id, JobState state, const std::string& error,
                    const std::string& result_json, std::optional<bool> exact,
                    double finished_at) override;
  std::optional<std::string> GetResult(std::int64_t id) override;
  std::vector<TraceRow> GetTrace(std::int64_t id, int after, int limit) override;
  std::vector<Improvement> GetImprovements(std::int64_t id) override;
  std::optional<std::string> GetCheckpoint(std::int64_t id) override;
  void RewindTo(std::int64_t id, int generation) override;
  bool DeleteJob(std::int64_t id) override;

  int schema_version();

 private:
  void Migrate();

  std::mutex mutex_;
  std::unique_ptr<SQLite::Database> db_;
};

}  // namespace springfit::server
