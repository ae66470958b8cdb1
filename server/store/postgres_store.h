// The shared store: one PostgreSQL database that several daemons, on one host or many, claim
// jobs from (server/store/job_store.h; README "Several daemons on one database").
//
// libpqxx, with prepared statements on every connection: one connection for the writes,
// a small pool for the reads (job.get, job.list, job.trace never wait behind a checkpoint),
// and one that LISTENs, so that a job submitted, released, cancelled or finished through one
// daemon wakes the others at once (their poll is the fallback). The lease clock is the
// server's (clock_timestamp()), never a host's, so hosts need not agree on the time.
//
// The schema is versioned in springfit_schema and migrated at start inside a transaction
// under an advisory lock: two daemons starting together do not both migrate.
//
// A lost connection (server restart, network) fails the call in progress with
// StoreUnavailable, and the next call connects again; nothing half-written is left, since
// every write is one transaction. A connection the server closed between calls is replaced
// before the next call uses it, so that call succeeds. A server that does not answer (stopped,
// partitioned, its machine frozen: the kernel still accepts the bytes, so no socket error comes)
// fails every call within Options::call_seconds: the wait for the slot's connection, the connecting
// and the statements alike. A watchdog shuts down the socket of a call past its deadline, which
// ends libpq's wait; the connection is then opened anew by the next call.
#pragma once
#include <atomic>
#include <condition_variable>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "server/mutex.h"
#include "server/store/job_store.h"

namespace springfit::server {

class PostgresStore final : public JobStore {
 public:
  static constexpr int kSchemaVersion = 5;

  struct Options {
    // Each call gives up after this long with StoreUnavailable (seconds, > 0): heartbeats,
    // claims and reads never hang on a server that does not answer. A call whose thread set a
    // shorter ScopedStoreDeadline (server.info) gives up after that.
    double call_seconds = 10.0;
    int readers = 2;  // connections for reads (>= 1)
    // Tests: runs as each call ends, before the watchdog stops watching it (a call whose
    // deadline passes after its last round trip).
    std::function<void()> on_call_end;
    void Validate() const;
  };

  // `url`: a libpq URI (postgresql://...), without a password; `password`: empty for libpq's
  // defaults (PGPASSWORD, PGPASSFILE). Connects, migrates; throws std::runtime_error.
  PostgresStore(const std::string& url, const std::string& password, Options options);
  PostgresStore(const std::string& url, const std::string& password);  // default Options
  ~PostgresStore() override;

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
  void SetChangeListener(std::function<void()> listener) override;
  std::string Describe() const override;

  int schema_version();

 private:
  struct Slot;  // one connection and the calls on it, one at a time (postgres_store.cpp)
  struct Call;  // a call's deadline (postgres_store.cpp)
  // The writer's connection, taken for `call` once no other call holds it.
  Slot& TakeWriter(const Call& call);
  // A reading connection no other call holds, taken for `call`: a slow read delays no other.
  Slot& TakeReader(const Call& call);
  // Runs f(connection) on the taken slot's connection, connecting first when needed, and lets
  // the slot go; maps the errors of a server that is not there to StoreUnavailable.
  template <typename F>
  auto With(Slot& slot, const Call& call, F&& f);
  template <typename F>
  auto Write(F&& f);
  template <typename F>
  auto Read(F&& f);
  // Quarantines job `id` when its row still cannot be read (server/store/store_rows.h), and
  // logs it when this call did: its quarantine, or nothing when the row is readable or gone.
  std::optional<QuarantinedJob> Quarantine(std::int64_t id);
  void Migrate();
  void ListenLoop();
  void WatchdogLoop();
  double CallLimit() const;

  Options options_;
  std::string conninfo_;  // the URL with the password and connect_timeout: never logged
  std::string url_;
  std::unique_ptr<Slot> writer_;
  std::vector<std::unique_ptr<Slot>> readers_;
  std::atomic<std::size_t> next_reader_{0};  // where the search for a free reader starts
  // A reader waiting for a free connection waits on reader_freed_ under readers_mutex_.
  Mutex readers_mutex_;
  std::condition_variable reader_freed_;

  Mutex listener_mutex_;
  std::function<void()> on_change_ SF_GUARDED_BY(listener_mutex_);
  std::atomic<bool> stopping_{false};
  std::thread listener_;
  std::thread watchdog_;
};

}  // namespace springfit::server
