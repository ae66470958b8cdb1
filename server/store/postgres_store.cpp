#include "server/store/postgres_store.h"

#include <poll.h>
#include <sys/socket.h>

#include <condition_variable>

#include <bit>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <pqxx/pqxx>

#include "engine/api/checkpoint.h"
#include "proto/search_codec.h"
#include "server/store/store_rows.h"

namespace springfit::server {
namespace {

// The advisory lock key under which a daemon migrates the schema ("springfi").
constexpr long long kMigrationLock = 0x737072696e676669LL;
// The one under which a submit counts the queue and inserts, so that max_queued holds for
// all daemons together.
constexpr long long kQueueLock = kMigrationLock + 1;
// The channel of the wake-ups (job submitted, released, cancelled, finished).
constexpr const char* kChannel = "springfit_jobs";
// The server's clock, in Unix seconds: the one clock every lease is read against.
#define SF_NOW "extract(epoch from clock_timestamp())::float8"

// Migration i takes the schema from version i to i + 1.
const char* const kMigrations[] = {
    R"sql(
CREATE TABLE jobs (
  id BIGSERIAL PRIMARY KEY,
  label TEXT NOT NULL,
  priority INTEGER NOT NULL,
  seed BIGINT NOT NULL,              -- the uint64 seed's bits
  idempotency_key TEXT UNIQUE,       -- NULL: none
  state TEXT NOT NULL,
  error TEXT NOT NULL DEFAULT '',
  scene_name TEXT NOT NULL,
  genes INTEGER NOT NULL,
  strategy TEXT NOT NULL,
  max_generations INTEGER NOT NULL,
  created_at DOUBLE PRECISION NOT NULL,
  started_at DOUBLE PRECISION NOT NULL DEFAULT 0,
  finished_at DOUBLE PRECISION NOT NULL DEFAULT 0,
  progress TEXT,                     -- the latest trace row as JSON
  checkpoint_generation INTEGER NOT NULL DEFAULT -1,
  exact BOOLEAN,                     -- NULL: unknown or not finished
  scene TEXT NOT NULL,
  result TEXT,
  lease_owner TEXT,                  -- the daemon running the job
  lease_epoch BIGINT NOT NULL DEFAULT 0,
  lease_expires DOUBLE PRECISION NOT NULL DEFAULT 0,
  cancel_requested BOOLEAN NOT NULL DEFAULT FALSE
);
CREATE INDEX jobs_to_claim ON jobs (priority DESC, id) WHERE state IN ('queued', 'running');
CREATE INDEX jobs_by_state ON jobs (state, id);
CREATE INDEX jobs_by_label ON jobs (label, id);
CREATE TABLE trace (
  job_id BIGINT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
  generation INTEGER NOT NULL,
  wall_seconds DOUBLE PRECISION NOT NULL,
  evaluations BIGINT NOT NULL,
  cache_hits BIGINT NOT NULL,
  best_cost DOUBLE PRECISION NOT NULL,
  best_normalized_error DOUBLE PRECISION NOT NULL,
  mean_cost DOUBLE PRECISION NOT NULL,
  missing INTEGER,
  extra INTEGER,
  PRIMARY KEY (job_id, generation)
);
CREATE TABLE improvements (
  job_id BIGINT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
  generation INTEGER NOT NULL,
  wall_seconds DOUBLE PRECISION NOT NULL,
  cost DOUBLE PRECISION NOT NULL,
  normalized_error DOUBLE PRECISION NOT NULL,
  missing INTEGER,
  extra INTEGER,
  genome BYTEA NOT NULL,             -- packed 8 genes per byte (engine/api/checkpoint.h)
  PRIMARY KEY (job_id, generation)
);
CREATE TABLE checkpoints (
  job_id BIGINT PRIMARY KEY REFERENCES jobs (id) ON DELETE CASCADE,
  generation INTEGER NOT NULL,
  state BYTEA NOT NULL               -- server/jobs/checkpoint_codec.h
);
)sql",
    // 2: jobs being prepared (state 'preparing', held by a lease), swept when it lapses. A
    // daemon older than this reads such a job as failed: the version makes it refuse the
    // store instead.
    R"sql(
CREATE INDEX jobs_preparing ON jobs (lease_expires) WHERE state = 'preparing';
)sql",
    // 3: a finished job's verdict and headline (proto/outcome_codec.h), for listings.
    R"sql(
ALTER TABLE jobs ADD COLUMN outcome TEXT;
)sql",
    // 4: jobs whose rows cannot be read, set aside (state 'quarantined'), an incident each
    // (server/store/job_store.h).
    R"sql(
CREATE TABLE quarantine (
  incident BIGSERIAL PRIMARY KEY,
  job_id BIGINT NOT NULL UNIQUE REFERENCES jobs (id) ON DELETE CASCADE,
  reason TEXT NOT NULL,
  quarantined_at DOUBLE PRECISION NOT NULL,
  previous_state TEXT NOT NULL      -- the job's, to set back once its row is repaired
);
)sql",
    // 5: every claim of a job, its lease history (server/store/job_store.h, LeaseRecord),
    // written with the lease it records, in the server's clock. (Claims before this version
    // are not in it.)
    R"sql(
CREATE TABLE leases (
  job_id BIGINT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
  epoch BIGINT NOT NULL,
  owner TEXT NOT NULL,
  granted_at DOUBLE PRECISION NOT NULL,
  expires_at DOUBLE PRECISION NOT NULL,  -- the last renewal's expiry
  ended_at DOUBLE PRECISION,             -- NULL: held, or lapsed
  ended TEXT,                            -- how it ended (kLeaseReleased ...)
  PRIMARY KEY (job_id, epoch)
);
)sql",
};
constexpr int kMigrationCount = static_cast<int>(std::size(kMigrations));
static_assert(kMigrationCount == PostgresStore::kSchemaVersion);

// The fence of every write of a running job: locks its row, so that no claim takes it
// before the write's transaction ends, and fails unless the lease is still the job's.
constexpr const char* kFence =
    "SELECT 1 FROM jobs WHERE id = $1 AND state IN ('running', 'preparing') AND lease_owner = "
    "$2 AND lease_epoch = $3 FOR UPDATE";

// Every statement, prepared on each connection when it opens.
const std::pair<const char*, const char*> kStatements[] = {
    {"find_key", "SELECT " SF_JOB_COLUMNS " FROM jobs WHERE idempotency_key = $1"},
    {"count_queued", "SELECT count(*) FROM jobs WHERE state = 'queued'"},
    {"count_waiting", "SELECT count(*) FROM jobs WHERE state IN ('queued', 'preparing')"},
    {"insert_job",
     "INSERT INTO jobs (label, priority, seed, idempotency_key, state, scene_name, genes, "
     "strategy, max_generations, created_at, scene, lease_owner, lease_epoch, lease_expires) "
     "VALUES ($1, $2, $3, NULLIF($4, ''), CASE WHEN $11 = '' THEN 'queued' ELSE 'preparing' END, "
     "$5, $6, $7, $8, $9, $10, NULLIF($11, ''), CASE WHEN $11 = '' THEN 0 ELSE 1 END, CASE WHEN "
     "$11 = '' THEN 0 ELSE " SF_NOW " + $12 END) RETURNING id"},
    {"finish_preparing",
     "UPDATE jobs SET state = CASE WHEN cancel_requested THEN 'cancelled' ELSE 'queued' END, "
     "finished_at = CASE WHEN cancel_requested THEN " SF_NOW " ELSE 0 END, genes = $4, strategy "
     "= $5, max_generations = $6, lease_owner = NULL, lease_expires = 0 WHERE id = $1 AND state "
     "= 'preparing' AND lease_owner = $2 AND lease_epoch = $3 RETURNING state"},
    {"drop_preparing",
     "DELETE FROM jobs WHERE id = $1 AND state = 'preparing' AND lease_owner = $2 AND "
     "lease_epoch = $3"},
    {"sweep_preparing", "DELETE FROM jobs WHERE state = 'preparing' AND lease_expires < " SF_NOW},
    {"get_scene", "SELECT scene FROM jobs WHERE id = $1"},
    {"get_listed", "SELECT " SF_LISTED_COLUMNS " FROM " SF_JOBS_LISTED " WHERE id = $1"},
    {"lock_job", "SELECT 1 FROM jobs WHERE id = $1 FOR UPDATE"},
    {"quarantine",
     "INSERT INTO quarantine (job_id, reason, quarantined_at, previous_state) VALUES "
     "($1, $2, " SF_NOW ", $3) RETURNING incident, quarantined_at"},
    {"set_aside",
     "UPDATE jobs SET state = 'quarantined', lease_owner = NULL, lease_expires = 0 WHERE id = $1"},
    {"unfinished", "SELECT " SF_LISTED_COLUMNS " FROM " SF_JOBS_LISTED
                   " WHERE state IN ('queued', 'running') ORDER BY priority DESC, id"},
    {"claim",
     "UPDATE jobs SET state = 'running', lease_owner = $1, lease_epoch = lease_epoch + 1, "
     "lease_expires = " SF_NOW " + $2, started_at = CASE WHEN started_at = 0 THEN " SF_NOW
     " ELSE started_at END WHERE id = (SELECT id FROM jobs WHERE state = 'queued' OR (state = "
     "'running' AND lease_expires < " SF_NOW
     ") ORDER BY priority DESC, id LIMIT 1 FOR UPDATE SKIP LOCKED) RETURNING " SF_JOB_COLUMNS
     ", lease_epoch, cancel_requested"},
    {"renew", "UPDATE jobs SET lease_expires = " SF_NOW
              " + $4 WHERE id = $1 AND state IN ('running', 'preparing') AND lease_owner = $2 AND "
              "lease_epoch = $3 RETURNING cancel_requested"},
    {"release",
     "UPDATE jobs SET lease_expires = 0 WHERE id = $1 AND state = 'running' AND lease_owner = "
     "$2 AND lease_epoch = $3"},
    {"fence", kFence},
    // The lease history (LeaseRecord), in the transaction of the write that changed the
    // lease: job $1's lease just granted (its clock read after the claim's); its last lease
    // renewed, or ended ($2: how), unless it had. (A write that ends a lease clears its
    // owner, never its epoch.)
    {"record_grant",
     "INSERT INTO leases (job_id, epoch, owner, granted_at, expires_at) SELECT id, lease_epoch, "
     "lease_owner, " SF_NOW ", lease_expires FROM jobs WHERE id = $1"},
    {"record_renewal",
     "UPDATE leases l SET expires_at = j.lease_expires FROM jobs j WHERE j.id = $1 AND l.job_id "
     "= j.id AND l.epoch = j.lease_epoch"},
    {"record_end",
     "UPDATE leases l SET ended_at = " SF_NOW ", ended = $2 FROM jobs j WHERE j.id = $1 AND "
     "l.job_id = j.id AND l.epoch = j.lease_epoch AND l.ended_at IS NULL"},
    {"lease_history", "SELECT " SF_LEASE_COLUMNS " FROM leases WHERE job_id = $1 ORDER BY epoch"},
    {"insert_trace",
     "INSERT INTO trace (job_id, generation, wall_seconds, evaluations, cache_hits, best_cost, "
     "best_normalized_error, mean_cost, missing, extra) SELECT $1, * FROM unnest($2::int[], "
     "$3::float8[], $4::bigint[], $5::bigint[], $6::float8[], $7::float8[], $8::float8[], "
     "$9::int[], $10::int[]) ON CONFLICT (job_id, generation) DO UPDATE SET wall_seconds = "
     "excluded.wall_seconds, evaluations = excluded.evaluations, cache_hits = "
     "excluded.cache_hits, best_cost = excluded.best_cost, best_normalized_error = "
     "excluded.best_normalized_error, mean_cost = excluded.mean_cost, missing = excluded.missing, "
     "extra = excluded.extra"},
    {"insert_improvement",
     "INSERT INTO improvements (job_id, generation, wall_seconds, cost, normalized_error, "
     "missing, extra, genome) VALUES ($1, $2, $3, $4, $5, NULLIF($6, -1), NULLIF($7, -1), $8) ON "
     "CONFLICT (job_id, generation) DO UPDATE SET wall_seconds = excluded.wall_seconds, cost = "
     "excluded.cost, normalized_error = excluded.normalized_error, missing = excluded.missing, "
     "extra = excluded.extra, genome = excluded.genome"},
    {"set_progress", "UPDATE jobs SET progress = $2 WHERE id = $1"},
    {"set_checkpoint",
     "INSERT INTO checkpoints (job_id, generation, state) VALUES ($1, $2, $3) ON CONFLICT "
     "(job_id) DO UPDATE SET generation = excluded.generation, state = excluded.state"},
    {"set_checkpoint_generation", "UPDATE jobs SET checkpoint_generation = $2 WHERE id = $1"},
    {"finish",
     "UPDATE jobs SET state = $2, error = $3, result = NULLIF($4, ''), exact = CASE $5::int WHEN "
     "-1 THEN NULL ELSE $5::int <> 0 END, finished_at = $6, outcome = NULLIF($7, ''), lease_owner "
     "= "
     "NULL, lease_expires = 0 WHERE id = $1"},
    {"drop_checkpoint", "DELETE FROM checkpoints WHERE job_id = $1"},
    {"rewind_trace", "DELETE FROM trace WHERE job_id = $1 AND generation > $2"},
    {"rewind_improvements", "DELETE FROM improvements WHERE job_id = $1 AND generation > $2"},
    // One statement: two (queued, then the others) could each miss a job that a daemon moves
    // from preparing to queued between them. (The right-hand sides read the row as it was.)
    {"cancel",
     "UPDATE jobs SET state = CASE WHEN state = 'queued' THEN 'cancelled' ELSE state END, "
     "finished_at = CASE WHEN state = 'queued' THEN " SF_NOW " ELSE finished_at END, "
     "cancel_requested = cancel_requested OR state <> 'queued' WHERE id = $1 AND state IN "
     "('queued', 'running', 'preparing') RETURNING state"},
    {"get_result", "SELECT result FROM jobs WHERE id = $1"},
    {"get_trace", "SELECT " SF_TRACE_COLUMNS
                  " FROM trace WHERE job_id = $1 AND generation > $2 ORDER BY generation LIMIT $3"},
    {"get_improvements",
     "SELECT " SF_IMPROVEMENT_COLUMNS
     " FROM improvements i JOIN jobs j ON j.id = i.job_id WHERE i.job_id = $1 AND i.generation > "
     "$2 ORDER BY i.generation LIMIT $3"},
    {"get_last_improvement",
     "SELECT " SF_IMPROVEMENT_COLUMNS
     " FROM improvements i JOIN jobs j ON j.id = i.job_id WHERE i.job_id = $1 ORDER BY "
     "i.generation DESC LIMIT 1"},
    {"get_checkpoint", "SELECT state FROM checkpoints WHERE job_id = $1"},
    {"delete_job",
     "DELETE FROM jobs WHERE id = $1 AND state IN ('succeeded', 'failed', 'cancelled')"},
    {"notify", "SELECT pg_notify($1, $2)"},
};

// A result row, as the row layer reads it (server/store/store_rows.h).
struct PgRow {
  const pqxx::row& q;
  bool Null(int i) const { return q[i].is_null(); }
  std::int64_t Int64(int i) const { return q[i].as<std::int64_t>(); }
  int Int(int i) const { return q[i].as<int>(); }
  double Double(int i) const { return q[i].as<double>(); }
  bool Bool(int i) const { return q[i].as<bool>(); }
  std::string Text(int i) const { return q[i].as<std::string>(); }
  std::string Blob(int i) const { return pqxx::binarystring(q[i]).str(); }
};

JobRecord ReadJob(const pqxx::row& q) {
  return rows::JobOf(PgRow{q});
}

// A PostgreSQL array literal ({1,2,NULL}) of the values `format` writes.
template <typename T, typename Format>
std::string ArrayLiteral(const std::vector<TraceRow>& rows, T TraceRow::*member, Format format) {
  std::string out = "{";
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (i) out += ',';
    out += format(rows[i].*member);
  }
  return out + "}";
}

std::string Float(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "Infinity" : "-Infinity";
  return fmt::format("{}", v);  // the shortest text that reads back as the same double
}

// SQLSTATEs of a server that is not there now: connection exceptions (class 08), shutting
// down or starting (57P01-57P03), out of resources (53). Anything else is a bug or bad data.
bool IsUnavailable(const std::string& sqlstate) {
  return sqlstate.rfind("08", 0) == 0 || sqlstate.rfind("57P", 0) == 0 ||
         sqlstate.rfind("53", 0) == 0;
}

std::string WithPassword(const std::string& url, const std::string& password) {
  if (password.empty()) return url;
  std::string encoded;
  for (const unsigned char c : password) {
    if (std::isalnum(c) || c == '-' || c == '_' || c == '.' || c == '~') {
      encoded += static_cast<char>(c);
    } else {
      encoded += fmt::format("%{:02X}", c);
    }
  }
  return url + (url.find('?') == std::string::npos ? "?" : "&") + "password=" + encoded;
}

class Wakeup final : public pqxx::notification_receiver {
 public:
  Wakeup(pqxx::connection_base& c, std::function<void()> on_change)
      : pqxx::notification_receiver(c, kChannel), on_change_(std::move(on_change)) {}
  void operator()(const std::string&, int) override {
    if (on_change_) on_change_();
  }

 private:
  std::function<void()> on_change_;
};

void Fence(pqxx::work& w, const Lease& lease) {
  if (w.exec_prepared("fence", lease.job_id, lease.owner, lease.epoch).empty()) {
    throw LeaseLost("job " + std::to_string(lease.job_id) + ": the lease of " + lease.owner +
                    " (claim " + std::to_string(lease.epoch) +
                    ") is no longer the job's: another daemon took it over, or it finished");
  }
}

// In a write transaction: job `id` quarantined when its row still cannot be read.
std::optional<rows::Quarantining> QuarantineIfDamaged(pqxx::work& w, std::int64_t id) {
  // The row locked first, then read by a statement of its own: daemons that find the damage
  // together take turns, and each reads the row as the one before left it (quarantined
  // once). (A join locked and read in one statement reads the quarantine table as it was
  // when that statement began.)
  w.exec_prepared("lock_job", id);
  const pqxx::result r = w.exec_prepared("get_listed", id);
  std::optional<rows::ListedJob> row;
  if (!r.empty()) row = rows::ListedJobOf(PgRow{r[0]});
  std::optional<rows::Quarantining> quarantining =
      rows::QuarantineIfDamaged(row, [&](const rows::ListedJob& damaged) {
        const pqxx::result q =
            w.exec_prepared("quarantine", damaged.id, damaged.damage, damaged.stored_state);
        return QuarantinedJob{damaged.id, q[0][0].as<std::int64_t>(), damaged.damage,
                              q[0][1].as<double>(), damaged.stored_state};
      });
  // (Again for a row quarantined before whose state was set back by hand.)
  if (quarantining) {
    w.exec_prepared("record_end", id, kLeaseQuarantined);
    w.exec_prepared("set_aside", id);
  }
  return quarantining;
}

// The listed rows of a result (SF_LISTED_COLUMNS).
std::vector<rows::ListedJob> ListedOf(const pqxx::result& r) {
  std::vector<rows::ListedJob> listed;
  for (const auto& row : r) listed.push_back(rows::ListedJobOf(PgRow{row}));
  return listed;
}

}  // namespace

struct PostgresStore::Slot {
  // One call at a time: `busy` under `mutex`, a caller waiting on `free` until its deadline.
  // (Not a std::timed_mutex: its timed lock is pthread_mutex_clocklock, which GCC 12's
  // ThreadSanitizer does not see, so every unlock would be reported.)
  Mutex mutex;
  std::condition_variable free;
  bool busy SF_GUARDED_BY(mutex) = false;
  // Asynchronous: its socket exists before the server has answered, so that the watchdog can
  // end a connect to a server that does not answer, as it ends a statement.
  std::unique_ptr<pqxx::asyncconnection> connection;
  // The call in progress, for the watchdog (under `watch`).
  Mutex watch;
  int socket SF_GUARDED_BY(watch) = -1;  // -1: no call, or not connected yet
  std::chrono::steady_clock::time_point deadline SF_GUARDED_BY(watch);
  // The watchdog shut the socket down: the call ran out of time.
  bool fired SF_GUARDED_BY(watch) = false;
  // When it fired on waking from a sleep far past its beat: the seconds the daemon itself did
  // not run (0 otherwise).
  double stalled_seconds SF_GUARDED_BY(watch) = 0.0;
};

void PostgresStore::Options::Validate() const {
  if (!(call_seconds > 0.0) || !std::isfinite(call_seconds))
    throw std::runtime_error("--store-timeout: must be a number of seconds > 0");
  if (readers < 1) throw std::runtime_error("the store needs at least one reading connection");
}

namespace {

// Whether the peer of `socket` has closed its end: a poll that neither waits nor reads (the
// server's farewell, if it sent one, stays unread; libpq reads only what a call asks for).
bool PeerClosed(int socket) {
  if (socket < 0) return true;
  pollfd p{socket, POLLRDHUP, 0};
  return ::poll(&p, 1, 0) > 0 && (p.revents & (POLLRDHUP | POLLHUP | POLLERR | POLLNVAL)) != 0;
}

// libpq's own bound on connecting (the listening connection's; the calls' connects are the
// watchdog's): whole seconds, at least 2 (libpq reads 1 as 2), unless the URL sets one.
std::string WithConnectTimeout(const std::string& conninfo, double seconds) {
  if (conninfo.find("connect_timeout=") != std::string::npos) return conninfo;
  const int whole = std::max(2, static_cast<int>(std::ceil(seconds)));
  return conninfo + (conninfo.find('?') == std::string::npos ? "?" : "&") +
         "connect_timeout=" + std::to_string(whole);
}

}  // namespace

PostgresStore::PostgresStore(const std::string& url, const std::string& password, Options options)
    : options_(options),
      conninfo_(WithConnectTimeout(WithPassword(url, password), options.call_seconds)),
      url_(url),
      writer_(std::make_unique<Slot>()) {
  options_.Validate();
  for (int i = 0; i < options_.readers; ++i) readers_.push_back(std::make_unique<Slot>());
  watchdog_ = std::thread([this] { WatchdogLoop(); });
  try {
    Migrate();
  } catch (const std::exception& e) {
    stopping_.store(true);
    watchdog_.join();
    throw std::runtime_error("cannot open the store " + url_ + ": " + e.what());
  }
  listener_ = std::thread([this] { ListenLoop(); });
}

PostgresStore::PostgresStore(const std::string& url, const std::string& password)
    : PostgresStore(url, password, Options{}) {}

PostgresStore::~PostgresStore() {
  stopping_.store(true);
  if (listener_.joinable()) listener_.join();
  if (watchdog_.joinable()) watchdog_.join();
}

double PostgresStore::CallLimit() const {
  const double scoped = ScopedStoreDeadline::Current();
  return scoped > 0.0 ? std::min(scoped, options_.call_seconds) : options_.call_seconds;
}

void PostgresStore::WatchdogLoop() {
  // Every 50 ms: a call past its deadline has its socket shut down (not closed: the descriptor
  // stays the connection's, which its owner drops when libpq reports the error).
  // A beat that comes a second or more late means the daemon itself did not run (SIGSTOP, a
  // host that froze or starved it): the call's time ran out on the daemon's side, not the
  // database's. It still ends (a daemon frozen past its lease must not write on), but its error
  // says whose the delay was.
  constexpr auto kBeat = std::chrono::milliseconds(50);
  constexpr auto kStalled = std::chrono::seconds(1);
  auto last = std::chrono::steady_clock::now();
  while (!stopping_.load()) {
    const auto now = std::chrono::steady_clock::now();
    const auto asleep = now - last;
    last = now;
    std::vector<Slot*> slots{writer_.get()};
    for (const auto& r : readers_) slots.push_back(r.get());
    for (Slot* slot : slots) {
      MutexLock lock(slot->watch);
      if (slot->socket >= 0 && !slot->fired && now >= slot->deadline) {
        ::shutdown(slot->socket, SHUT_RDWR);
        slot->fired = true;
        slot->stalled_seconds =
            asleep >= kStalled ? std::chrono::duration<double>(asleep - kBeat).count() : 0.0;
      }
    }
    std::this_thread::sleep_for(kBeat);
  }
}

std::string PostgresStore::Describe() const {
  return url_;
}

struct PostgresStore::Call {
  explicit Call(double limit)
      : deadline(std::chrono::steady_clock::now() +
                 std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                     std::chrono::duration<double>(limit))),
        late(fmt::format("the database did not answer within {:g} s", limit)) {}
  std::chrono::steady_clock::time_point deadline;
  std::string late;  // the error past the deadline
};

PostgresStore::Slot& PostgresStore::TakeWriter(const Call& call) {
  MutexLock lock(writer_->mutex);
  while (writer_->busy && lock.WaitUntil(writer_->free, call.deadline)) {
  }
  if (writer_->busy)
    throw StoreUnavailable(call.late + " (its connection is held by a call that has not returned)");
  writer_->busy = true;
  return *writer_;
}

PostgresStore::Slot& PostgresStore::TakeReader(const Call& call) {
  // From a different reader at each call: the reads are spread over the connections.
  const std::size_t first = next_reader_.fetch_add(1);
  MutexLock lock(readers_mutex_);
  while (true) {
    for (std::size_t i = 0; i < readers_.size(); ++i) {
      Slot& slot = *readers_[(first + i) % readers_.size()];
      MutexLock slot_lock(slot.mutex);
      if (!slot.busy) {
        slot.busy = true;
        return slot;
      }
    }
    if (!lock.WaitUntil(reader_freed_, call.deadline)) {
      throw StoreUnavailable(call.late +
                             " (every reading connection is held by a call that has not returned)");
    }
  }
}

template <typename F>
auto PostgresStore::With(Slot& slot, const Call& call, F&& f) {
  const auto& deadline = call.deadline;
  const std::string& late = call.late;
  struct Release {
    PostgresStore& store;
    Slot& slot;
    ~Release() {
      {
        MutexLock lock(slot.mutex);
        slot.busy = false;
      }
      slot.free.notify_one();
      // (Taken and released: a reader that found every slot busy is waiting by now.)
      { MutexLock readers(store.readers_mutex_); }
      store.reader_freed_.notify_all();
    }
  } release{*this, slot};
  // The watchdog's view of this call: armed once the connection has a socket, disarmed
  // before the connection is dropped (its descriptor may then be reused).
  const auto arm = [&] {
    MutexLock watch(slot.watch);
    slot.socket = slot.connection->sock();
    slot.deadline = deadline;
    slot.fired = false;
    slot.stalled_seconds = 0.0;
  };
  const auto disarm = [&] {
    MutexLock watch(slot.watch);
    slot.socket = -1;
    return slot.fired;
  };
  // The error of a call the watchdog ended: the database's delay, or the daemon's own.
  const auto timed_out_error = [&] {
    MutexLock watch(slot.watch);
    if (!(slot.stalled_seconds > 0.0)) return late;
    return fmt::format(
        "the store call ran past its limit while this daemon itself did not run for {:.1f} s "
        "(stopped, or its host froze or starved it): the delay was the daemon's, not the "
        "database's",
        slot.stalled_seconds);
  };
  // The watchdog may fire after the call's last round trip: the call succeeded, but the
  // socket is shut all the same, and the connection's next call would fail on it (a progress
  // write, which interrupts its job). Such a connection goes: the next call opens a new one.
  struct Disarm {
    const decltype(disarm)& off;
    const std::function<void()>& on_call_end;
    Slot& slot;
    ~Disarm() {
      if (on_call_end) on_call_end();
      if (off()) slot.connection.reset();
    }
  } disarm_at_end{disarm, options_.on_call_end, slot};
  const auto drop = [&](const std::string& what) {
    const bool timed_out = disarm();
    slot.connection.reset();
    return StoreUnavailable(timed_out ? timed_out_error() : what);
  };
  try {
    // A connection whose server closed its end since the last call (a restart, an
    // administrator's termination, a backend killed; or a write that committed just before its
    // session ended) is replaced before it is used: this call opens a new one instead of
    // failing on it. (A server that went without closing, a host that lost power, is found by
    // the call itself: the store is unavailable, and the next call opens anew.)
    if (slot.connection && slot.connection->is_open() && PeerClosed(slot.connection->sock()))
      slot.connection.reset();
    if (!slot.connection || !slot.connection->is_open()) {
      slot.connection = std::make_unique<pqxx::asyncconnection>(conninfo_);
      arm();
      for (const auto& [name, sql] : kStatements) slot.connection->prepare(name, sql);
      // The connect completes here, under the watchdog: a first round trip, since some calls
      // quote text (which needs the server's encoding) before their first statement. It also
      // bounds how long this session may sit in an open transaction: a daemon frozen inside one
      // (SIGSTOP, a stalled host) holds the job's row lock, and the claims of the other daemons
      // (FOR UPDATE SKIP LOCKED) would pass over the job for as long as it stays frozen; the
      // server ends such a session after one call limit, and the lock with it.
      pqxx::nontransaction(*slot.connection)
          .exec(fmt::format("SET idle_in_transaction_session_timeout = {}",
                            static_cast<long long>(std::ceil(1000.0 * options_.call_seconds))));
    } else {
      arm();
    }
    return f(*slot.connection);
  } catch (const pqxx::broken_connection& e) {
    throw drop(std::string("the database connection failed: ") + e.what());
  } catch (const pqxx::in_doubt_error& e) {
    throw drop(std::string("the database connection failed during a commit: ") + e.what());
  } catch (const pqxx::sql_error& e) {
    // A statement whose connection went under it (the server stopped or restarted: libpq's
    // "server closed the connection unexpectedly") can come as an SQL error with no SQLSTATE,
    // the server having said nothing: the connection is gone, not the statement wrong. (The
    // hour's soak met one as job.submit's internal error after a PostgreSQL restart.)
    const bool connection_lost =
        e.sqlstate().empty() || !slot.connection || !slot.connection->is_open();
    if (IsUnavailable(e.sqlstate()) || connection_lost || disarm())
      throw drop(std::string("the database is unavailable: ") + e.what());
    throw std::runtime_error(std::string("database: ") + e.what());
  }
}

template <typename F>
auto PostgresStore::Write(F&& f) {
  const Call call(CallLimit());
  return With(TakeWriter(call), call, std::forward<F>(f));
}

template <typename F>
auto PostgresStore::Read(F&& f) {
  const Call call(CallLimit());
  return With(TakeReader(call), call, std::forward<F>(f));
}

void PostgresStore::Migrate() {
  Write([&](pqxx::connection_base& c) {
    pqxx::work w(c);
    w.exec("SELECT pg_advisory_xact_lock(" + std::to_string(kMigrationLock) + ")");
    w.exec("CREATE TABLE IF NOT EXISTS springfit_schema (version INTEGER NOT NULL)");
    const pqxx::result r = w.exec("SELECT version FROM springfit_schema");
    int version = 0;
    if (r.empty()) {
      w.exec("INSERT INTO springfit_schema (version) VALUES (0)");
    } else {
      version = r[0][0].as<int>();
    }
    if (version > kSchemaVersion) {
      throw std::runtime_error("the database has schema version " + std::to_string(version) +
                               ", newer than this springfitd's " + std::to_string(kSchemaVersion));
    }
    for (int v = version; v < kSchemaVersion; ++v) w.exec(kMigrations[v]);
    if (version < kSchemaVersion) {
      w.exec("UPDATE springfit_schema SET version = " + std::to_string(kSchemaVersion));
      spdlog::info("store {}: schema migrated from version {} to {}", url_, version,
                   kSchemaVersion);
    }
    w.commit();
  });
}

int PostgresStore::schema_version() {
  return Read([&](pqxx::connection_base& c) {
    pqxx::nontransaction w(c);  // one statement: no BEGIN and COMMIT round trips
    return w.exec("SELECT version FROM springfit_schema")[0][0].as<int>();
  });
}

void PostgresStore::SetChangeListener(std::function<void()> listener) {
  MutexLock lock(listener_mutex_);
  on_change_ = std::move(listener);
}

void PostgresStore::ListenLoop() {
  double backoff = 0.1;
  while (!stopping_.load()) {
    try {
      pqxx::connection c(conninfo_);
      Wakeup wakeup(c, [this] {
        MutexLock lock(listener_mutex_);
        if (on_change_) on_change_();
      });
      backoff = 0.1;
      // Notifications sent while this connection was down are lost: the callers' polls
      // cover them. A wake-up now makes them look at once.
      {
        MutexLock lock(listener_mutex_);
        if (on_change_) on_change_();
      }
      while (!stopping_.load()) c.await_notification(0, 200000);
    } catch (const std::exception& e) {
      if (stopping_.load()) break;
      spdlog::debug("store {}: listening connection lost ({}); reconnecting", url_, e.what());
      const auto until =
          std::chrono::steady_clock::now() + std::chrono::milliseconds(int(backoff * 1000));
      while (!stopping_.load() && std::chrono::steady_clock::now() < until)
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      backoff = std::min(5.0, backoff * 2);
    }
  }
}

JobStore::Created PostgresStore::CreateJob(const NewJob& job, int max_queued) {
  return Write([&](pqxx::connection_base& c) -> Created {
    pqxx::work w(c);
    // Serialises submits (all daemons): the count and the insert are one step, and two
    // submits of one idempotency key cannot both insert.
    w.exec("SELECT pg_advisory_xact_lock(" + std::to_string(kQueueLock) + ")");
    const JobRecord& r = job.record;
    if (!r.idempotency_key.empty()) {
      const pqxx::result found = w.exec_prepared("find_key", r.idempotency_key);
      if (!found.empty()) return {ReadJob(found[0]), false, false, {}};
    }
    if (w.exec_prepared("count_waiting")[0][0].as<int>() >= max_queued) return {r, false, true, {}};
    const bool preparing = !job.preparing_owner.empty();
    const pqxx::result inserted =
        w.exec_prepared("insert_job", r.label, r.priority, std::bit_cast<std::int64_t>(r.seed),
                        r.idempotency_key, r.scene_name, r.genes, r.strategy, r.max_generations,
                        r.created_at, job.scene_json, job.preparing_owner, job.lease_seconds);
    if (preparing) w.exec_prepared("record_grant", inserted[0][0].as<std::int64_t>());
    // (A preparing job is announced when it is queued: no daemon can claim it before.)
    if (!preparing) w.exec_prepared("notify", kChannel, "queued");
    w.commit();
    Created created{r, true, false, {}};
    created.job.id = inserted[0][0].as<std::int64_t>();
    created.job.state = preparing ? JobState::kPreparing : JobState::kQueued;
    if (preparing) created.lease = {created.job.id, job.preparing_owner, 1};
    return created;
  });
}

JobState PostgresStore::FinishPreparing(const Lease& lease, const JobRecord& prepared) {
  return Write([&](pqxx::connection_base& c) {
    pqxx::work w(c);
    const pqxx::result r =
        w.exec_prepared("finish_preparing", lease.job_id, lease.owner, lease.epoch, prepared.genes,
                        prepared.strategy, prepared.max_generations);
    if (r.empty()) {
      throw LeaseLost("job " + std::to_string(lease.job_id) +
                      ": no longer being prepared here (its lease expired)");
    }
    const JobState state =
        proto::ParseJobState(r[0][0].as<std::string>()).value_or(JobState::kQueued);
    w.exec_prepared("record_end", lease.job_id, kLeasePrepared);
    w.exec_prepared("notify", kChannel, state == JobState::kQueued ? "queued" : "finished");
    w.commit();
    return state;
  });
}

void PostgresStore::DropPreparing(const Lease& lease) {
  Write([&](pqxx::connection_base& c) {
    pqxx::work w(c);
    w.exec_prepared("drop_preparing", lease.job_id, lease.owner, lease.epoch);
    w.commit();
  });
}

std::optional<QuarantinedJob> PostgresStore::Quarantine(std::int64_t id) {
  return rows::Announced(Write([&](pqxx::connection_base& c) {
    pqxx::work w(c);
    std::optional<rows::Quarantining> found = QuarantineIfDamaged(w, id);
    w.commit();
    return found;
  }));
}

std::optional<JobRecord> PostgresStore::GetJob(std::int64_t id) {
  const std::vector<rows::ListedJob> row = Read([&](pqxx::connection_base& c) {
    pqxx::nontransaction w(c);  // one statement: no BEGIN and COMMIT round trips
    return ListedOf(w.exec_prepared("get_listed", id));
  });
  if (row.empty()) return std::nullopt;
  return rows::ReadableJob(row[0], [this](std::int64_t job) { return Quarantine(job); });
}

std::optional<std::string> PostgresStore::GetScene(std::int64_t id) {
  return Read([&](pqxx::connection_base& c) -> std::optional<std::string> {
    pqxx::nontransaction w(c);  // one statement: no BEGIN and COMMIT round trips
    const pqxx::result r = w.exec_prepared("get_scene", id);
    if (r.empty()) return std::nullopt;
    return r[0][0].as<std::string>();
  });
}

JobPage PostgresStore::ListJobs(const JobFilter& f) {
  std::vector<rows::ListedJob> listed = Read([&](pqxx::connection_base& c) {
    pqxx::nontransaction w(c);  // one statement: no BEGIN and COMMIT round trips
    // Four shapes of one query; the parameters are bound, never spliced.
    std::string sql = std::string("SELECT " SF_LISTED_COLUMNS " FROM " SF_JOBS_LISTED " WHERE ") +
                      (!f.newest_first  ? "id > $1"
                       : f.after_id > 0 ? "id < $1"
                                        : "$1::bigint = 0");
    int n = 2;
    if (f.state) sql += " AND state = $" + std::to_string(n++);
    if (f.label) sql += " AND label = $" + std::to_string(n++);
    sql += std::string(f.newest_first ? " ORDER BY id DESC" : " ORDER BY id") + " LIMIT $" +
           std::to_string(n);
    const std::string state = f.state ? std::string(proto::JobStateName(*f.state)) : "";
    pqxx::result r;
    if (f.state && f.label) {
      r = w.exec_params(sql, f.after_id, state, *f.label, f.limit + 1);
    } else if (f.state) {
      r = w.exec_params(sql, f.after_id, state, f.limit + 1);
    } else if (f.label) {
      r = w.exec_params(sql, f.after_id, *f.label, f.limit + 1);
    } else {
      r = w.exec_params(sql, f.after_id, f.limit + 1);
    }
    return ListedOf(r);
  });
  return rows::PageOf(std::move(listed), f.limit,
                      [this](std::int64_t id) { return Quarantine(id); });
}

std::vector<JobRecord> PostgresStore::UnfinishedJobs() {
  return rows::ReadableJobs(Read([&](pqxx::connection_base& c) {
                              pqxx::nontransaction w(c);  // one statement
                              return ListedOf(w.exec_prepared("unfinished"));
                            }),
                            [this](std::int64_t id) { return Quarantine(id); });
}

int PostgresStore::CountQueued() {
  return Read([&](pqxx::connection_base& c) {
    pqxx::nontransaction w(c);  // one statement: no BEGIN and COMMIT round trips
    return w.exec_prepared("count_queued")[0][0].as<int>();
  });
}

std::map<JobState, int> PostgresStore::CountJobs() {
  return Read([&](pqxx::connection_base& c) {
    pqxx::nontransaction w(c);
    std::map<JobState, int> counts;
    for (const auto& row : w.exec("SELECT state, count(*) FROM jobs GROUP BY state")) {
      if (const auto state = proto::ParseJobState(row[0].as<std::string>()))
        counts[*state] = row[1].as<int>();
    }
    return counts;
  });
}

std::optional<Claim> PostgresStore::ClaimNext(const std::string& owner, double lease_seconds) {
  return Write([&](pqxx::connection_base& c) -> std::optional<Claim> {
    // A job whose row cannot be read is quarantined as it was (its claim undone), and the
    // next one taken instead: one damaged row must not hold up the queue.
    while (true) {
      pqxx::work w(c);
      // Submissions whose daemon stopped renewing them while they were prepared: never
      // answered.
      w.exec_prepared("sweep_preparing");
      w.exec("SAVEPOINT claim");
      const pqxx::result r = w.exec_prepared("claim", owner, lease_seconds);
      if (r.empty()) {
        w.commit();
        return std::nullopt;
      }
      const std::int64_t id = r[0][0].as<std::int64_t>();
      std::optional<rows::Quarantining> quarantined;
      Claim claim;
      try {
        claim.job = ReadJob(r[0]);
      } catch (const StoreCorrupt&) {
        w.exec("ROLLBACK TO SAVEPOINT claim");
        quarantined = QuarantineIfDamaged(w, id);
        if (!quarantined) throw;  // (not set aside: it would be claimed again)
      }
      if (!quarantined) w.exec_prepared("record_grant", id);
      w.commit();
      if (quarantined) {
        rows::Announced(*quarantined);
        continue;
      }
      claim.lease = {id, owner, r[0][rows::kJobColumnCount].as<std::int64_t>()};
      claim.cancel_requested = r[0][rows::kJobColumnCount + 1].as<bool>();
      return claim;
    }
  });
}

LeaseStatus PostgresStore::RenewLease(const Lease& lease, double lease_seconds) {
  return Write([&](pqxx::connection_base& c) {
    pqxx::work w(c);
    const pqxx::result r =
        w.exec_prepared("renew", lease.job_id, lease.owner, lease.epoch, lease_seconds);
    if (!r.empty()) w.exec_prepared("record_renewal", lease.job_id);
    w.commit();
    LeaseStatus status;
    if (!r.empty()) {
      status.held = true;
      status.cancel_requested = r[0][0].as<bool>();
    }
    return status;
  });
}

void PostgresStore::ReleaseLease(const Lease& lease) {
  Write([&](pqxx::connection_base& c) {
    pqxx::work w(c);
    if (w.exec_prepared("release", lease.job_id, lease.owner, lease.epoch).affected_rows() > 0) {
      w.exec_prepared("record_end", lease.job_id, kLeaseReleased);
      w.exec_prepared("notify", kChannel, "released");
    }
    w.commit();
  });
}

void PostgresStore::SaveProgress(const Lease& lease, const ProgressBatch& b) {
  Write([&](pqxx::connection_base& c) {
    pqxx::work w(c);
    Fence(w, lease);
    const std::int64_t id = lease.job_id;
    if (!b.trace.empty()) {
      const auto integer = [](auto v) { return std::to_string(v); };
      const auto count = [](int v) { return v < 0 ? std::string("NULL") : std::to_string(v); };
      w.exec_prepared("insert_trace", id, ArrayLiteral(b.trace, &TraceRow::generation, integer),
                      ArrayLiteral(b.trace, &TraceRow::wall_seconds, Float),
                      ArrayLiteral(b.trace, &TraceRow::evaluations, integer),
                      ArrayLiteral(b.trace, &TraceRow::cache_hits, integer),
                      ArrayLiteral(b.trace, &TraceRow::best_cost, Float),
                      ArrayLiteral(b.trace, &TraceRow::best_normalized_error, Float),
                      ArrayLiteral(b.trace, &TraceRow::mean_cost, Float),
                      ArrayLiteral(b.trace, &TraceRow::missing, count),
                      ArrayLiteral(b.trace, &TraceRow::extra, count));
    }
    for (const Improvement& m : b.improvements) {
      const std::string genome = PackGenome(m.genome);
      w.exec_prepared("insert_improvement", id, m.generation, m.wall_seconds, m.cost,
                      m.normalized_error, m.missing, m.extra,
                      pqxx::binarystring(genome.data(), genome.size()));
    }
    if (b.latest) w.exec_prepared("set_progress", id, proto::TraceRowToJson(*b.latest).dump());
    if (b.checkpoint) {
      w.exec_prepared("set_checkpoint", id, b.checkpoint_generation,
                      pqxx::binarystring(b.checkpoint->data(), b.checkpoint->size()));
      w.exec_prepared("set_checkpoint_generation", id, b.checkpoint_generation);
    }
    w.commit();
  });
}

void PostgresStore::MarkFinished(const Lease& lease, const JobEnd& end) {
  Write([&](pqxx::connection_base& c) {
    pqxx::work w(c);
    Fence(w, lease);
    w.exec_prepared("finish", lease.job_id, std::string(proto::JobStateName(end.state)), end.error,
                    end.result_json, end.exact ? (*end.exact ? 1 : 0) : -1, end.finished_at,
                    end.outcome_json);
    // A finished job is never resumed: its checkpoint is dead weight.
    w.exec_prepared("record_end", lease.job_id, kLeaseFinished);
    w.exec_prepared("drop_checkpoint", lease.job_id);
    w.exec_prepared("notify", kChannel, "finished");
    w.commit();
  });
}

void PostgresStore::RewindTo(const Lease& lease, int generation) {
  Write([&](pqxx::connection_base& c) {
    pqxx::work w(c);
    Fence(w, lease);
    w.exec_prepared("rewind_trace", lease.job_id, generation);
    w.exec_prepared("rewind_improvements", lease.job_id, generation);
    w.commit();
  });
}

JobStore::CancelOutcome PostgresStore::RequestCancel(std::int64_t id) {
  return Write([&](pqxx::connection_base& c) {
    pqxx::work w(c);
    CancelOutcome outcome = CancelOutcome::kNotActive;
    const pqxx::result r = w.exec_prepared("cancel", id);
    if (!r.empty()) {
      outcome = r[0][0].as<std::string>() == "cancelled" ? CancelOutcome::kCancelled
                                                         : CancelOutcome::kRequested;
    }
    if (outcome != CancelOutcome::kNotActive) w.exec_prepared("notify", kChannel, "cancel");
    w.commit();
    return outcome;
  });
}

std::optional<std::string> PostgresStore::GetResult(std::int64_t id) {
  return Read([&](pqxx::connection_base& c) -> std::optional<std::string> {
    pqxx::nontransaction w(c);  // one statement: no BEGIN and COMMIT round trips
    const pqxx::result r = w.exec_prepared("get_result", id);
    if (r.empty() || r[0][0].is_null()) return std::nullopt;
    return r[0][0].as<std::string>();
  });
}

std::vector<TraceRow> PostgresStore::GetTrace(std::int64_t id, int after, int limit) {
  return Read([&](pqxx::connection_base& c) {
    pqxx::nontransaction w(c);  // one statement: no BEGIN and COMMIT round trips
    std::vector<TraceRow> trace;
    for (const auto& q : w.exec_prepared("get_trace", id, after, limit))
      trace.push_back(rows::TraceRowOf(PgRow{q}));
    return trace;
  });
}

std::vector<Improvement> PostgresStore::GetImprovements(std::int64_t id,
                                                        const ImprovementPage& page) {
  return Read([&](pqxx::connection_base& c) {
    pqxx::nontransaction w(c);  // one statement: no BEGIN and COMMIT round trips
    std::vector<Improvement> out;
    // (LIMIT NULL: no limit.)
    const pqxx::result found =
        page.last ? w.exec_prepared("get_last_improvement", id)
                  : w.exec_prepared("get_improvements", id, page.after,
                                    page.limit > 0 ? std::optional<long long>(page.limit)
                                                   : std::optional<long long>());
    for (const auto& q : found) out.push_back(rows::ImprovementOf(PgRow{q}));
    return out;
  });
}

std::optional<std::string> PostgresStore::GetCheckpoint(std::int64_t id) {
  return Read([&](pqxx::connection_base& c) -> std::optional<std::string> {
    pqxx::nontransaction w(c);  // one statement: no BEGIN and COMMIT round trips
    const pqxx::result r = w.exec_prepared("get_checkpoint", id);
    if (r.empty()) return std::nullopt;
    return pqxx::binarystring(r[0][0]).str();
  });
}

std::vector<LeaseRecord> PostgresStore::LeaseHistory(std::int64_t id) {
  return Read([&](pqxx::connection_base& c) {
    pqxx::nontransaction w(c);
    std::vector<LeaseRecord> out;
    for (const auto& row : w.exec_prepared("lease_history", id))
      out.push_back(rows::LeaseOf(PgRow{row}));
    return out;
  });
}

bool PostgresStore::DeleteJob(std::int64_t id) {
  return Write([&](pqxx::connection_base& c) {
    pqxx::work w(c);
    const bool deleted = w.exec_prepared("delete_job", id).affected_rows() > 0;
    w.commit();
    return deleted;
  });
}

}  // namespace springfit::server
