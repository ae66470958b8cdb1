// The embedded store: one SQLite database file in WAL mode (server/store/job_store.h), for one
// daemon: opening it takes an advisory lock on the file, so a second springfitd on the same
// database is refused, and frees the leases a crashed or stopped daemon left.
//
// One writing connection behind a mutex and a pool of reading ones, each opened anew after an
// I/O error or a full disk. The daemon's writes are small and batched (a job flushes its
// progress about once a second), so a single writer is never the bottleneck; in WAL mode the
// readers (job.get, job.list, traces, results) read the last committed state without waiting
// for a write, a checkpoint or a lock held by another process (sqlite3, a backup).
// synchronous=FULL: a flushed batch survives a power cut, not only a crash of the daemon.
//
// The schema's version is PRAGMA user_version; opening a database migrates it to the
// current version in one transaction, and refuses a database of a newer springfit.
#pragma once
#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "server/mutex.h"
#include "server/store/job_store.h"
#include "server/store/store_rows.h"

namespace SQLite {
class Database;
class Exception;
class Statement;
}  // namespace SQLite

namespace springfit::server {

class SqliteStore final : public JobStore {
 public:
  static constexpr int kSchemaVersion = 6;

  // Opens or creates the database; throws std::runtime_error with the reason.
  explicit SqliteStore(const std::string& path);
  ~SqliteStore() override;

  Created CreateJob(const NewJob& job, int max_queued) override;
  JobState FinishPreparing(const Lease& lease, const JobRecord& prepared) override;
  void DropPreparing(const Lease& lease) override;
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
  void MarkFinished(const Lease& lease, const JobEnd& end) override;
  void RewindTo(const Lease& lease, int generation) override;
  CancelOutcome RequestCancel(std::int64_t id) override;
  std::optional<std::string> GetResult(std::int64_t id) override;
  std::vector<TraceRow> GetTrace(std::int64_t id, int after, int limit) override;
  using JobStore::GetImprovements;
  std::vector<Improvement> GetImprovements(std::int64_t id, const ImprovementPage& page) override;
  std::optional<std::string> GetCheckpoint(std::int64_t id) override;
  std::vector<LeaseRecord> LeaseHistory(std::int64_t id) override;
  bool DeleteJob(std::int64_t id) override;
  std::string Describe() const override;

  int schema_version();

 private:
  // Readers beside the one writer: in WAL mode they read the last committed state without
  // waiting for a write or a checkpoint in progress.
  static constexpr int kReaders = 4;
  // What a connection remembers of its failures.
  struct ConnectionState {
    // Set by an I/O error: after one, SQLite can fail every later statement of the same
    // connection with 'database disk image is malformed' while the file is intact.
    bool reopen = false;
    bool io_error = false;  // an I/O error since the last operation that succeeded
  };
  struct Reader {
    Mutex mutex;
    std::unique_ptr<SQLite::Database> db SF_GUARDED_BY(mutex);  // opened on first use
    ConnectionState state SF_GUARDED_BY(mutex);
  };

  // Quarantines job `id` when its row still cannot be read (server/store/store_rows.h), and
  // logs it when this call did: its quarantine, or nothing when the row is readable or gone.
  std::optional<QuarantinedJob> Quarantine(std::int64_t id);
  // The rows of a SELECT of SF_LISTED_COLUMNS, read on a reader.
  std::vector<rows::ListedJob> ReadListed(const std::string& sql,
                                          const std::function<void(SQLite::Statement&)>& bind);
  // A connection on path_ with this store's settings (WAL, synchronous, busy timeout).
  std::unique_ptr<SQLite::Database> Open(bool read_only) const;
  void Migrate() SF_REQUIRES(mutex_);
  // Runs f(connection) on the writer, under its mutex.
  template <typename F>
  auto Run(F&& f) -> decltype(f(std::declval<SQLite::Database&>()));
  // Runs f(connection) on a reader (reads only).
  template <typename F>
  auto Read(F&& f) -> decltype(f(std::declval<SQLite::Database&>()));
  // Runs f on `db`, first opening it anew when an I/O error left it unusable, and maps
  // SQLite's exceptions to the store's (Rethrow).
  template <typename F>
  auto OnConnection(std::unique_ptr<SQLite::Database>& db, ConnectionState& state, bool read_only,
                    F& f) -> decltype(f(std::declval<SQLite::Database&>()));
  // I/O failures and a full disk make the store unavailable (server/store/job_store.h), not wrong,
  // and mark the connection for reopening; a damaged file is named as such.
  [[noreturn]] void Rethrow(const SQLite::Exception& e, ConnectionState& state) const;

  std::string path_;
  int lock_fd_ = -1;
  Mutex mutex_;  // the writer's
  std::unique_ptr<SQLite::Database> db_ SF_GUARDED_BY(mutex_);
  ConnectionState writer_state_ SF_GUARDED_BY(mutex_);
  std::vector<std::unique_ptr<Reader>> readers_;
  std::atomic<unsigned> next_reader_{0};
};

}  // namespace springfit::server
