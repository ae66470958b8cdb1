// The embedded store: one SQLite database file in WAL mode (server/job_store.h), for one
// daemon: opening it takes an advisory lock on the file, so a second springfitd on the same
// database is refused, and frees the leases a crashed or stopped daemon left.
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
  static constexpr int kSchemaVersion = 2;

  // Opens or creates the database; throws std::runtime_error with the reason.
  explicit SqliteStore(const std::string& path);
  ~SqliteStore() override;

  Created CreateJob(const NewJob& job, int max_queued) override;
  std::optional<JobRecord> GetJob(std::int64_t id) override;
  std::optional<std::string> GetScene(std::int64_t id) override;
  JobPage ListJobs(const JobFilter& filter) override;
  std::vector<JobRecord> UnfinishedJobs() override;
  int CountQueued() override;
  std::map<JobState, int> CountJobs() override;
  std::optional<Claim> ClaimNext(const std::string& owner, double lease_seconds) override;
  LeaseStatus RenewLease(const Lease& lease, double lease_seconds) override;
  void ReleaseLease(const Lease& lease) override;
  void SaveProgress(const Lease& lease, const ProgressBatch& batch) override;
  void MarkFinished(const Lease& lease, JobState state, const std::string& error,
                    const std::string& result_json, std::optional<bool> exact,
                    double finished_at) override;
  void RewindTo(const Lease& lease, int generation) override;
  CancelOutcome RequestCancel(std::int64_t id) override;
  std::optional<std::string> GetResult(std::int64_t id) override;
  std::vector<TraceRow> GetTrace(std::int64_t id, int after, int limit) override;
  std::vector<Improvement> GetImprovements(std::int64_t id) override;
  std::optional<std::string> GetCheckpoint(std::int64_t id) override;
  bool DeleteJob(std::int64_t id) override;
  std::string Describe() const override;

  int schema_version();

 private:
  void Migrate();

  std::string path_;
  int lock_fd_ = -1;
  std::mutex mutex_;
  std::unique_ptr<SQLite::Database> db_;
};

}  // namespace springfit::server
