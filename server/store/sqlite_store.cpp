#include "server/store/sqlite_store.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <bit>
#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include <SQLiteCpp/SQLiteCpp.h>
#include <spdlog/spdlog.h>
#include <sqlite3.h>

#include "engine/api/checkpoint.h"
#include "proto/search_codec.h"
#include "server/store/store_rows.h"
#include "server/store/unix_time.h"

namespace springfit::server {
namespace {

// Migration i takes the schema from version i to i + 1.
const char* const kMigrations[] = {
    R"sql(
CREATE TABLE jobs (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  label TEXT NOT NULL,
  priority INTEGER NOT NULL,
  seed INTEGER NOT NULL,             -- the uint64 seed's bits
  idempotency_key TEXT UNIQUE,       -- NULL: none
  state TEXT NOT NULL,
  error TEXT NOT NULL DEFAULT '',
  scene_name TEXT NOT NULL,
  genes INTEGER NOT NULL,
  strategy TEXT NOT NULL,
  max_generations INTEGER NOT NULL,
  created_at REAL NOT NULL,
  started_at REAL NOT NULL DEFAULT 0,
  finished_at REAL NOT NULL DEFAULT 0,
  progress TEXT,                     -- the latest trace row as JSON
  checkpoint_generation INTEGER NOT NULL DEFAULT -1,
  exact INTEGER,                     -- NULL: unknown or not finished
  scene TEXT NOT NULL,
  result TEXT
);
CREATE INDEX jobs_by_state ON jobs (state, priority DESC, id);
CREATE INDEX jobs_by_label ON jobs (label, id);
CREATE TABLE trace (
  job_id INTEGER NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
  generation INTEGER NOT NULL,
  wall_seconds REAL NOT NULL,
  evaluations INTEGER NOT NULL,
  cache_hits INTEGER NOT NULL,
  best_cost REAL NOT NULL,
  best_normalized_error REAL NOT NULL,
  mean_cost REAL NOT NULL,
  missing INTEGER,
  extra INTEGER,
  PRIMARY KEY (job_id, generation)
) WITHOUT ROWID;
CREATE TABLE improvements (
  job_id INTEGER NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
  generation INTEGER NOT NULL,
  wall_seconds REAL NOT NULL,
  cost REAL NOT NULL,
  normalized_error REAL NOT NULL,
  missing INTEGER,
  extra INTEGER,
  genome BLOB NOT NULL,              -- packed 8 genes per byte (engine/api/checkpoint.h)
  PRIMARY KEY (job_id, generation)
);
CREATE TABLE checkpoints (
  job_id INTEGER PRIMARY KEY REFERENCES jobs (id) ON DELETE CASCADE,
  generation INTEGER NOT NULL,
  state BLOB NOT NULL                -- server/jobs/checkpoint_codec.h
);
)sql",
    // 2: the lease a daemon holds a running job by (server/store/job_store.h) and job.cancel as a
    // request its runner reads.
    R"sql(
ALTER TABLE jobs ADD COLUMN lease_owner TEXT;
ALTER TABLE jobs ADD COLUMN lease_epoch INTEGER NOT NULL DEFAULT 0;
ALTER TABLE jobs ADD COLUMN lease_expires REAL NOT NULL DEFAULT 0;
ALTER TABLE jobs ADD COLUMN cancel_requested INTEGER NOT NULL DEFAULT 0;
-- What a claim scans: the unfinished jobs in claim order, however many finished ones there are.
CREATE INDEX jobs_to_claim ON jobs (priority DESC, id) WHERE state IN ('queued', 'running');
)sql",
    // 3: jobs being prepared (state 'preparing', held by a lease), swept when it lapses.
    R"sql(
CREATE INDEX jobs_preparing ON jobs (lease_expires) WHERE state = 'preparing';
)sql",
    // 4: a finished job's verdict and headline (proto/outcome_codec.h), for listings.
    R"sql(
ALTER TABLE jobs ADD COLUMN outcome TEXT;
)sql",
    // 5: jobs whose rows cannot be read, set aside (state 'quarantined'), an incident each
    // (server/store/job_store.h).
    R"sql(
CREATE TABLE quarantine (
  incident INTEGER PRIMARY KEY AUTOINCREMENT,
  job_id INTEGER NOT NULL UNIQUE REFERENCES jobs (id) ON DELETE CASCADE,
  reason TEXT NOT NULL,
  quarantined_at REAL NOT NULL,
  previous_state TEXT NOT NULL      -- the job's, to set back once its row is repaired
);
)sql",
    // 6: every claim of a job, its lease history (server/store/job_store.h, LeaseRecord),
    // written with the lease it records. (Claims before this version are not in it.)
    R"sql(
CREATE TABLE leases (
  job_id INTEGER NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
  epoch INTEGER NOT NULL,
  owner TEXT NOT NULL,
  granted_at REAL NOT NULL,
  expires_at REAL NOT NULL,         -- the last renewal's expiry
  ended_at REAL,                    -- NULL: held, or lapsed
  ended TEXT,                       -- how it ended (kLeaseReleased ...)
  PRIMARY KEY (job_id, epoch)
) WITHOUT ROWID;
)sql",
};
constexpr int kMigrationCount = static_cast<int>(std::size(kMigrations));
static_assert(kMigrationCount == SqliteStore::kSchemaVersion);

// A row of a stepped statement, as the row layer reads it (server/store/store_rows.h).
struct SqliteRow {
  SQLite::Statement& q;
  bool Null(int i) const { return q.getColumn(i).isNull(); }
  std::int64_t Int64(int i) const { return q.getColumn(i).getInt64(); }
  int Int(int i) const { return q.getColumn(i).getInt(); }
  double Double(int i) const { return q.getColumn(i).getDouble(); }
  bool Bool(int i) const { return q.getColumn(i).getInt() != 0; }
  std::string Text(int i) const { return q.getColumn(i).getString(); }
  std::string Blob(int i) const { return q.getColumn(i).getString(); }
};

JobRecord ReadJob(SQLite::Statement& q) {
  return rows::JobOf(SqliteRow{q});
}

void BindCount(SQLite::Statement& q, int index, int count) {
  if (count < 0) {
    q.bind(index);
  } else {
    q.bind(index, count);
  }
}
void BindBlob(SQLite::Statement& q, int index, const std::string& bytes) {
  if (bytes.size() > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
    throw std::runtime_error("store: a blob over 2 GiB");
  }
  q.bind(index, bytes.data(), static_cast<int>(bytes.size()));
}

// An UPDATE ... RETURNING of one row, its row read: steps it to its end, where SQLite
// commits it (autocommit), so that a commit that fails (a full disk, an I/O error) throws
// here rather than in the statement's destructor, which ignores it.
void FinishReturning(SQLite::Statement& q) {
  while (q.executeStep()) {
  }
}

// Runs `sql`, whose three parameters are the lease's job, owner and epoch: the rows it changed.
int ExecOnLease(SQLite::Database& db, const char* sql, const Lease& lease) {
  SQLite::Statement q(db, sql);
  q.bind(1, lease.job_id);
  q.bind(2, lease.owner);
  q.bind(3, lease.epoch);
  return q.exec();
}

// The lease history (LeaseRecord): job `id`'s current lease, just granted at `now` by the
// statement before, as a claim of its own.
void RecordGrant(SQLite::Database& db, std::int64_t id, double now) {
  SQLite::Statement q(db,
                      "INSERT INTO leases (job_id, epoch, owner, granted_at, expires_at) SELECT "
                      "id, lease_epoch, lease_owner, ?, lease_expires FROM jobs WHERE id = ?");
  q.bind(1, now);
  q.bind(2, id);
  q.exec();
}

// The lease history: job `id`'s last lease ended at `now`, `how` (kLeaseReleased ...), unless
// it had. (A write that ends a lease clears its owner, never its epoch.)
void RecordEnd(SQLite::Database& db, std::int64_t id, double now, const char* how) {
  SQLite::Statement q(db,
                      "UPDATE leases SET ended_at = ?, ended = ? WHERE job_id = ? AND epoch = "
                      "(SELECT lease_epoch FROM jobs WHERE id = ?) AND ended_at IS NULL");
  q.bind(1, now);
  q.bind(2, how);
  q.bind(3, id);
  q.bind(4, id);
  q.exec();
}

// Throws LeaseLost unless `lease` is the running job's current one. Inside the transaction
// of the write it fences: SQLite runs one transaction at a time, so nothing claims between.
void CheckLease(SQLite::Database& db, const Lease& lease) {
  SQLite::Statement q(db,
                      "SELECT 1 FROM jobs WHERE id = ? AND state IN ('running', 'preparing') AND "
                      "lease_owner = ? AND lease_epoch = ?");
  q.bind(1, lease.job_id);
  q.bind(2, lease.owner);
  q.bind(3, lease.epoch);
  if (!q.executeStep()) {
    throw LeaseLost("job " + std::to_string(lease.job_id) + ": the lease of " + lease.owner +
                    " (claim " + std::to_string(lease.epoch) +
                    ") is no longer the job's: another daemon took it over, or it finished");
  }
}

// The job to claim next at `now` (the highest priority, then the oldest, of the queued jobs
// and the running ones whose lease expired), if any.
std::optional<std::int64_t> PickNext(SQLite::Database& db, double now) {
  // In claim order from the partial index: the first match ends the scan (the planner, left
  // alone, sorts every queued job at each claim).
  SQLite::Statement pick(db,
                         "SELECT id FROM jobs INDEXED BY jobs_to_claim WHERE state IN ('queued', "
                         "'running') AND (state = 'queued' OR lease_expires < ?) ORDER BY "
                         "priority DESC, id LIMIT 1");
  pick.bind(1, now);
  if (!pick.executeStep()) return std::nullopt;
  return pick.getColumn(0).getInt64();
}

// Job `id` running, held by `owner` for `lease_seconds` from `now`, in a new claim (its epoch
// incremented).
void TakeJob(SQLite::Database& db, std::int64_t id, const std::string& owner, double now,
             double lease_seconds) {
  SQLite::Statement take(
      db,
      "UPDATE jobs SET state = 'running', lease_owner = ?, lease_epoch = lease_epoch + 1, "
      "lease_expires = ?, started_at = CASE WHEN started_at = 0 THEN ? ELSE started_at END "
      "WHERE id = ?");
  take.bind(1, owner);
  take.bind(2, now + lease_seconds);
  take.bind(3, now);
  take.bind(4, id);
  take.exec();
  RecordGrant(db, id, now);
}

// The claim of job `id` just taken by `owner`; StoreCorrupt when its row cannot be read.
Claim ReadClaim(SQLite::Database& db, std::int64_t id, const std::string& owner) {
  SQLite::Statement q(
      db, "SELECT " SF_JOB_COLUMNS ", lease_epoch, cancel_requested FROM jobs WHERE id = ?");
  q.bind(1, id);
  q.executeStep();
  Claim claim;
  claim.job = ReadJob(q);
  claim.lease = {id, owner, q.getColumn(rows::kJobColumnCount).getInt64()};
  claim.cancel_requested = q.getColumn(rows::kJobColumnCount + 1).getInt() != 0;
  return claim;
}

// In the writer's transaction: job `id` quarantined when its row still cannot be read.
std::optional<rows::Quarantining> QuarantineIfDamaged(SQLite::Database& db, std::int64_t id) {
  SQLite::Statement q(db, "SELECT " SF_LISTED_COLUMNS " FROM " SF_JOBS_LISTED " WHERE id = ?");
  q.bind(1, id);
  std::optional<rows::ListedJob> row;
  if (q.executeStep()) row = rows::ListedJobOf(SqliteRow{q});
  q.reset();
  std::optional<rows::Quarantining> quarantining =
      rows::QuarantineIfDamaged(row, [&](const rows::ListedJob& damaged) {
        QuarantinedJob quarantined{damaged.id, 0, damaged.damage, UnixNow(), damaged.stored_state};
        SQLite::Statement insert(db,
                                 "INSERT INTO quarantine (job_id, reason, quarantined_at, "
                                 "previous_state) VALUES (?, ?, ?, ?)");
        insert.bind(1, damaged.id);
        insert.bind(2, damaged.damage);
        insert.bind(3, quarantined.quarantined_at);
        insert.bind(4, damaged.stored_state);
        insert.exec();
        quarantined.incident = db.getLastInsertRowid();
        return quarantined;
      });
  // (Again for a row quarantined before whose state was set back by hand.)
  if (quarantining) {
    RecordEnd(db, id, UnixNow(), kLeaseQuarantined);
    SQLite::Statement set_aside(db,
                                "UPDATE jobs SET state = 'quarantined', lease_owner = NULL, "
                                "lease_expires = 0 WHERE id = ?");
    set_aside.bind(1, id);
    set_aside.exec();
  }
  return quarantining;
}

}  // namespace

SqliteStore::SqliteStore(const std::string& path) : path_(path) {
  // A new database holds every submitted scene and result: created readable by the daemon's
  // user alone (SQLite gives its -wal and -shm files the database file's permissions).
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd >= 0) {
    ::close(fd);
  } else if (errno != EEXIST) {
    throw std::runtime_error("cannot create the database " + path + ": " + std::strerror(errno));
  }
  // One daemon per SQLite database: a second one would run the first one's jobs too (and its
  // start below would free their leases). An advisory lock on the file, held until closed.
  lock_fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (lock_fd_ < 0 || ::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    if (lock_fd_ >= 0) ::close(lock_fd_);
    throw std::runtime_error(
        err == EWOULDBLOCK
            ? "the database " + path +
                  " is in use by another springfitd (one daemon per SQLite database; several "
                  "daemons share a PostgreSQL store: --store postgresql://...)"
            : "cannot lock the database " + path + ": " + std::strerror(err));
  }
  try {
    MutexLock lock(mutex_);  // (no other thread yet: for the analysis, server/mutex.h)
    db_ = Open(/*read_only=*/false);
    // A damaged file is refused at the start, not found job by job later (quick_check reads
    // every page once: linear in the file's size, without the index cross-checks).
    {
      SQLite::Statement check(*db_, "PRAGMA quick_check(1)");
      if (check.executeStep() && check.getColumn(0).getString() != "ok") {
        throw std::runtime_error("the database " + path + " is damaged (PRAGMA quick_check: " +
                                 check.getColumn(0).getString() +
                                 "); restore it from a backup, or move it aside to start anew");
      }
    }
    Migrate();
    // The lock says no other daemon runs: the leases of running jobs are a dead daemon's
    // (this one's before a crash or a stop), and its jobs resume at once.
    {
      SQLite::Transaction tx(*db_, SQLite::TransactionBehavior::IMMEDIATE);
      SQLite::Statement gone(
          *db_,
          "UPDATE leases SET ended_at = ?, ended = ? WHERE ended_at IS NULL AND "
          "epoch = (SELECT lease_epoch FROM jobs WHERE jobs.id = leases.job_id)");
      gone.bind(1, UnixNow());
      gone.bind(2, kLeaseHolderGone);
      gone.exec();
      db_->exec("UPDATE jobs SET lease_expires = 0 WHERE state = 'running'");
      tx.commit();
    }
    // Its submissions being prepared were never answered: no client holds their ids.
    db_->exec("DELETE FROM jobs WHERE state = 'preparing'");
    for (int i = 0; i < kReaders; ++i) readers_.push_back(std::make_unique<Reader>());
  } catch (const SQLite::Exception& e) {
    ::close(lock_fd_);
    throw std::runtime_error("cannot open the database " + path + ": " + e.what());
  } catch (...) {
    ::close(lock_fd_);
    throw;
  }
}

std::unique_ptr<SQLite::Database> SqliteStore::Open(bool read_only) const {
  auto db = std::make_unique<SQLite::Database>(
      path_, read_only ? SQLite::OPEN_READONLY : SQLite::OPEN_READWRITE);
  db->setBusyTimeout(5000);
  if (!read_only) {
    db->exec("PRAGMA journal_mode = WAL");
    db->exec("PRAGMA synchronous = FULL");
    db->exec("PRAGMA foreign_keys = ON");
  }
  return db;
}

// Write transactions are IMMEDIATE: the file's write lock is taken at BEGIN, where the busy
// timeout waits for it. A deferred one that read first could not wait for it later: SQLite
// answers 'database is locked' at once rather than risk a deadlock.
template <typename F>
auto SqliteStore::Run(F&& f) -> decltype(f(std::declval<SQLite::Database&>())) {
  MutexLock lock(mutex_);
  return OnConnection(db_, writer_state_, /*read_only=*/false, f);
}

template <typename F>
auto SqliteStore::Read(F&& f) -> decltype(f(std::declval<SQLite::Database&>())) {
  // A free reader if there is one, else the next in turn (reads of one job are short).
  for (const std::unique_ptr<Reader>& r : readers_) {
    if (r->mutex.try_lock()) {
      MutexLock lock(r->mutex, std::adopt_lock);
      return OnConnection(r->db, r->state, /*read_only=*/true, f);
    }
  }
  Reader& r = *readers_[next_reader_.fetch_add(1) % readers_.size()];
  MutexLock lock(r.mutex);
  return OnConnection(r.db, r.state, /*read_only=*/true, f);
}

template <typename F>
auto SqliteStore::OnConnection(std::unique_ptr<SQLite::Database>& db, ConnectionState& state,
                               bool read_only, F& f)
    -> decltype(f(std::declval<SQLite::Database&>())) {
  try {
    if (!db || state.reopen) {
      db.reset();
      db = Open(read_only);
      if (state.reopen)
        spdlog::warn("database {}: a new {} connection after an I/O error", path_,
                     read_only ? "reading" : "writing");
      state.reopen = false;
    }
    if constexpr (std::is_void_v<decltype(f(*db))>) {
      f(*db);
      state.io_error = false;
    } else {
      auto result = f(*db);
      state.io_error = false;
      return result;
    }
  } catch (const SQLite::Exception& e) {
    Rethrow(e, state);
  }
}

void SqliteStore::Rethrow(const SQLite::Exception& e, ConnectionState& state) const {
  const int code = e.getErrorCode() & 0xff;
  switch (code) {
    case SQLITE_FULL:
      state.reopen = state.io_error = true;
      throw StoreUnavailable("the disk holding the database " + path_ +
                             " is full; nothing was written (the daemon resumes by itself once "
                             "there is space)");
    case SQLITE_IOERR:
      state.reopen = state.io_error = true;
      throw StoreUnavailable("the database " + path_ + " cannot be read or written (" + e.what() +
                             "); nothing was written");
    case SQLITE_CORRUPT:
    case SQLITE_NOTADB:
      if (state.io_error) {
        // The connection's view after the failed write, not the file: read it anew.
        state.reopen = true;
        throw StoreUnavailable("the database " + path_ +
                               " could not be read after an I/O error; it is opened anew");
      }
      throw std::runtime_error("the database " + path_ + " is damaged (" + e.what() +
                               "): stop the daemon and restore it from a backup, or move it "
                               "aside to start anew");
    case SQLITE_CANTOPEN:
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
    case SQLITE_READONLY:
      throw StoreUnavailable("the database " + path_ + " cannot be written (" + e.what() + ")");
    default:
      throw std::runtime_error("database " + path_ + ": " + e.what());
  }
}

SqliteStore::~SqliteStore() {
  readers_.clear();
  db_.reset();
  ::close(lock_fd_);
}

std::string SqliteStore::Describe() const {
  return "sqlite:///" + path_;
}

int SqliteStore::schema_version() {
  MutexLock lock(mutex_);
  return db_->execAndGet("PRAGMA user_version").getInt();
}

void SqliteStore::Migrate() {
  SQLite::Transaction tx(*db_, SQLite::TransactionBehavior::IMMEDIATE);
  const int version = db_->execAndGet("PRAGMA user_version").getInt();
  if (version > kSchemaVersion) {
    throw std::runtime_error("the database has schema version " + std::to_string(version) +
                             ", newer than this springfitd's " + std::to_string(kSchemaVersion));
  }
  for (int v = version; v < kSchemaVersion; ++v) db_->exec(kMigrations[v]);
  db_->exec("PRAGMA user_version = " + std::to_string(kSchemaVersion));
  tx.commit();
}

JobStore::Created SqliteStore::CreateJob(const NewJob& job, int max_queued) {
  return Run([&](SQLite::Database& db) -> Created {
    SQLite::Transaction tx(db, SQLite::TransactionBehavior::IMMEDIATE);
    const JobRecord& r = job.record;
    if (!r.idempotency_key.empty()) {
      SQLite::Statement q(db, "SELECT " SF_JOB_COLUMNS " FROM jobs WHERE idempotency_key = ?");
      q.bind(1, r.idempotency_key);
      if (q.executeStep()) return {ReadJob(q), false, false, {}};
    }
    if (db.execAndGet("SELECT count(*) FROM jobs WHERE state IN ('queued', 'preparing')")
            .getInt() >= max_queued) {
      return {r, false, true, {}};
    }
    const bool preparing = !job.preparing_owner.empty();
    const JobState state = preparing ? JobState::kPreparing : JobState::kQueued;
    SQLite::Statement insert(
        db,
        "INSERT INTO jobs (label, priority, seed, idempotency_key, state, scene_name, genes, "
        "strategy, max_generations, created_at, scene, lease_owner, lease_epoch, lease_expires) "
        "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
    insert.bind(1, r.label);
    insert.bind(2, r.priority);
    insert.bind(3, std::bit_cast<std::int64_t>(r.seed));
    if (r.idempotency_key.empty()) {
      insert.bind(4);
    } else {
      insert.bind(4, r.idempotency_key);
    }
    insert.bind(5, std::string(proto::JobStateName(state)));
    insert.bind(6, r.scene_name);
    insert.bind(7, r.genes);
    insert.bind(8, r.strategy);
    insert.bind(9, r.max_generations);
    insert.bind(10, r.created_at);
    insert.bind(11, job.scene_json);
    if (preparing) {
      insert.bind(12, job.preparing_owner);
    } else {
      insert.bind(12);
    }
    insert.bind(13, preparing ? 1 : 0);
    const double now = UnixNow();
    insert.bind(14, preparing ? now + job.lease_seconds : 0.0);
    insert.exec();
    Created created{r, true, false, {}};
    created.job.id = db.getLastInsertRowid();
    if (preparing) RecordGrant(db, created.job.id, now);
    created.job.state = state;
    if (preparing) created.lease = {created.job.id, job.preparing_owner, 1};
    tx.commit();
    return created;
  });
}

JobState SqliteStore::FinishPreparing(const Lease& lease, const JobRecord& prepared) {
  return Run([&](SQLite::Database& db) {
    SQLite::Transaction tx(db, SQLite::TransactionBehavior::IMMEDIATE);
    const double now = UnixNow();
    SQLite::Statement q(
        db,
        "UPDATE jobs SET state = CASE WHEN cancel_requested THEN 'cancelled' ELSE 'queued' END, "
        "finished_at = CASE WHEN cancel_requested THEN ? ELSE 0 END, genes = ?, strategy = ?, "
        "max_generations = ?, lease_owner = NULL, lease_expires = 0 WHERE id = ? AND state = "
        "'preparing' AND lease_owner = ? AND lease_epoch = ? RETURNING state");
    q.bind(1, now);
    q.bind(2, prepared.genes);
    q.bind(3, prepared.strategy);
    q.bind(4, prepared.max_generations);
    q.bind(5, lease.job_id);
    q.bind(6, lease.owner);
    q.bind(7, lease.epoch);
    if (!q.executeStep()) {
      throw LeaseLost("job " + std::to_string(lease.job_id) +
                      ": no longer being prepared here (its lease expired)");
    }
    const JobState state =
        proto::ParseJobState(q.getColumn(0).getString()).value_or(JobState::kQueued);
    FinishReturning(q);
    RecordEnd(db, lease.job_id, now, kLeasePrepared);
    tx.commit();
    return state;
  });
}

void SqliteStore::DropPreparing(const Lease& lease) {
  Run([&](SQLite::Database& db) {
    ExecOnLease(db,
                "DELETE FROM jobs WHERE id = ? AND state = 'preparing' AND lease_owner = ? AND "
                "lease_epoch = ?",
                lease);
  });
}

std::optional<QuarantinedJob> SqliteStore::Quarantine(std::int64_t id) {
  return rows::Announced(Run([&](SQLite::Database& db) {
    SQLite::Transaction tx(db, SQLite::TransactionBehavior::IMMEDIATE);
    std::optional<rows::Quarantining> found = QuarantineIfDamaged(db, id);
    tx.commit();
    return found;
  }));
}

std::vector<rows::ListedJob> SqliteStore::ReadListed(
    const std::string& sql, const std::function<void(SQLite::Statement&)>& bind) {
  return Read([&](SQLite::Database& db) {
    SQLite::Statement q(db, sql);
    bind(q);
    std::vector<rows::ListedJob> listed;
    while (q.executeStep()) listed.push_back(rows::ListedJobOf(SqliteRow{q}));
    return listed;
  });
}

std::optional<JobRecord> SqliteStore::GetJob(std::int64_t id) {
  const std::vector<rows::ListedJob> row =
      ReadListed("SELECT " SF_LISTED_COLUMNS " FROM " SF_JOBS_LISTED " WHERE id = ?",
                 [&](SQLite::Statement& q) { q.bind(1, id); });
  if (row.empty()) return std::nullopt;
  return rows::ReadableJob(row[0], [this](std::int64_t job) { return Quarantine(job); });
}

std::optional<std::string> SqliteStore::GetScene(std::int64_t id) {
  return Read([&](SQLite::Database& db) -> std::optional<std::string> {
    SQLite::Statement q(db, "SELECT scene FROM jobs WHERE id = ?");
    q.bind(1, id);
    if (!q.executeStep()) return std::nullopt;
    return q.getColumn(0).getString();
  });
}

JobPage SqliteStore::ListJobs(const JobFilter& f) {
  std::string sql = std::string("SELECT " SF_LISTED_COLUMNS " FROM " SF_JOBS_LISTED " WHERE ") +
                    (!f.newest_first  ? "id > ?"
                     : f.after_id > 0 ? "id < ?"
                                      : "? = 0");
  if (f.state) sql += " AND state = ?";
  if (f.label) sql += " AND label = ?";
  sql += f.newest_first ? " ORDER BY id DESC LIMIT ?" : " ORDER BY id LIMIT ?";
  std::vector<rows::ListedJob> listed = ReadListed(sql, [&](SQLite::Statement& q) {
    int i = 1;
    q.bind(i++, f.after_id);
    if (f.state) q.bind(i++, std::string(proto::JobStateName(*f.state)));
    if (f.label) q.bind(i++, *f.label);
    q.bind(i++, f.limit + 1);  // one more tells whether there is a next page
  });
  return rows::PageOf(std::move(listed), f.limit,
                      [this](std::int64_t id) { return Quarantine(id); });
}

std::vector<JobRecord> SqliteStore::UnfinishedJobs() {
  return rows::ReadableJobs(
      ReadListed("SELECT " SF_LISTED_COLUMNS " FROM " SF_JOBS_LISTED
                 " WHERE state IN ('queued', 'running') ORDER BY priority DESC, id",
                 [](SQLite::Statement&) {}),
      [this](std::int64_t id) { return Quarantine(id); });
}

int SqliteStore::CountQueued() {
  return Read([&](SQLite::Database& db) {
    return db.execAndGet("SELECT count(*) FROM jobs WHERE state = 'queued'").getInt();
  });
}

std::map<JobState, int> SqliteStore::CountJobs() {
  return Read([&](SQLite::Database& db) {
    SQLite::Statement q(db, "SELECT state, count(*) FROM jobs GROUP BY state");
    std::map<JobState, int> counts;
    while (q.executeStep()) {
      if (const auto state = proto::ParseJobState(q.getColumn(0).getString()))
        counts[*state] = q.getColumn(1).getInt();
    }
    return counts;
  });
}

std::optional<Claim> SqliteStore::ClaimNext(const std::string& owner, double lease_seconds) {
  std::vector<rows::Quarantining> quarantined;
  std::optional<Claim> claim = Run([&](SQLite::Database& db) -> std::optional<Claim> {
    quarantined.clear();  // (a transaction rolled back quarantines nothing)
    SQLite::Transaction tx(db, SQLite::TransactionBehavior::IMMEDIATE);
    const double now = UnixNow();
    // Submissions whose daemon stopped renewing them while they were prepared: never answered.
    SQLite::Statement sweep(db, "DELETE FROM jobs WHERE state = 'preparing' AND lease_expires < ?");
    sweep.bind(1, now);
    sweep.exec();
    std::optional<Claim> taken;
    // A job whose row cannot be read is quarantined as it was (its claim undone), and the
    // next one taken instead: one damaged row must not hold up the queue.
    while (const std::optional<std::int64_t> id = PickNext(db, now)) {
      db.exec("SAVEPOINT claim");
      TakeJob(db, *id, owner, now, lease_seconds);
      try {
        taken = ReadClaim(db, *id, owner);
        db.exec("RELEASE claim");
        break;
      } catch (const StoreCorrupt&) {
        db.exec("ROLLBACK TO claim");
        db.exec("RELEASE claim");
        std::optional<rows::Quarantining> q = QuarantineIfDamaged(db, *id);
        if (!q) throw;  // (not set aside: it would be picked again)
        quarantined.push_back(std::move(*q));
      }
    }
    tx.commit();
    return taken;
  });
  for (const rows::Quarantining& q : quarantined) rows::Announced(q);
  return claim;
}

LeaseStatus SqliteStore::RenewLease(const Lease& lease, double lease_seconds) {
  return Run([&](SQLite::Database& db) {
    SQLite::Transaction tx(db, SQLite::TransactionBehavior::IMMEDIATE);
    const double expires = UnixNow() + lease_seconds;
    SQLite::Statement q(db,
                        "UPDATE jobs SET lease_expires = ? WHERE id = ? AND state IN ('running', "
                        "'preparing') AND lease_owner = ? AND lease_epoch = ? RETURNING "
                        "cancel_requested");
    q.bind(1, expires);
    q.bind(2, lease.job_id);
    q.bind(3, lease.owner);
    q.bind(4, lease.epoch);
    LeaseStatus status;
    if (q.executeStep()) {
      status.held = true;
      status.cancel_requested = q.getColumn(0).getInt() != 0;
      FinishReturning(q);
      SQLite::Statement renewed(db,
                                "UPDATE leases SET expires_at = ? WHERE job_id = ? AND epoch = ?");
      renewed.bind(1, expires);
      renewed.bind(2, lease.job_id);
      renewed.bind(3, lease.epoch);
      renewed.exec();
    }
    tx.commit();
    return status;
  });
}

void SqliteStore::ReleaseLease(const Lease& lease) {
  Run([&](SQLite::Database& db) {
    SQLite::Transaction tx(db, SQLite::TransactionBehavior::IMMEDIATE);
    if (ExecOnLease(db,
                    "UPDATE jobs SET lease_expires = 0 WHERE id = ? AND state = 'running' AND "
                    "lease_owner = ? AND lease_epoch = ?",
                    lease) > 0) {
      RecordEnd(db, lease.job_id, UnixNow(), kLeaseReleased);
    }
    tx.commit();
  });
}

void SqliteStore::SaveProgress(const Lease& lease, const ProgressBatch& b) {
  Run([&](SQLite::Database& db) {
    SQLite::Transaction tx(db, SQLite::TransactionBehavior::IMMEDIATE);
    CheckLease(db, lease);
    const std::int64_t id = lease.job_id;
    if (!b.trace.empty()) {
      SQLite::Statement q(db,
                          "INSERT OR REPLACE INTO trace (job_id, generation, wall_seconds, "
                          "evaluations, cache_hits, best_cost, best_normalized_error, mean_cost, "
                          "missing, extra) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
      for (const TraceRow& r : b.trace) {
        q.bind(1, id);
        q.bind(2, r.generation);
        q.bind(3, r.wall_seconds);
        q.bind(4, static_cast<std::int64_t>(r.evaluations));
        q.bind(5, static_cast<std::int64_t>(r.cache_hits));
        q.bind(6, r.best_cost);
        q.bind(7, r.best_normalized_error);
        q.bind(8, r.mean_cost);
        BindCount(q, 9, r.missing);
        BindCount(q, 10, r.extra);
        q.exec();
        q.reset();
      }
    }
    if (!b.improvements.empty()) {
      SQLite::Statement q(db,
                          "INSERT OR REPLACE INTO improvements (job_id, generation, wall_seconds, "
                          "cost, normalized_error, missing, extra, genome) VALUES (?, ?, ?, ?, ?, "
                          "?, ?, ?)");
      for (const Improvement& m : b.improvements) {
        q.bind(1, id);
        q.bind(2, m.generation);
        q.bind(3, m.wall_seconds);
        q.bind(4, m.cost);
        q.bind(5, m.normalized_error);
        BindCount(q, 6, m.missing);
        BindCount(q, 7, m.extra);
        BindBlob(q, 8, PackGenome(m.genome));
        q.exec();
        q.reset();
      }
    }
    if (b.latest) {
      SQLite::Statement q(db, "UPDATE jobs SET progress = ? WHERE id = ?");
      q.bind(1, proto::TraceRowToJson(*b.latest).dump());
      q.bind(2, id);
      q.exec();
    }
    if (b.checkpoint) {
      SQLite::Statement q(
          db, "INSERT OR REPLACE INTO checkpoints (job_id, generation, state) VALUES (?, ?, ?)");
      q.bind(1, id);
      q.bind(2, b.checkpoint_generation);
      BindBlob(q, 3, *b.checkpoint);
      q.exec();
      SQLite::Statement u(db, "UPDATE jobs SET checkpoint_generation = ? WHERE id = ?");
      u.bind(1, b.checkpoint_generation);
      u.bind(2, id);
      u.exec();
    }
    tx.commit();
  });
}

void SqliteStore::MarkFinished(const Lease& lease, const JobEnd& end) {
  Run([&](SQLite::Database& db) {
    SQLite::Transaction tx(db, SQLite::TransactionBehavior::IMMEDIATE);
    CheckLease(db, lease);
    SQLite::Statement q(db,
                        "UPDATE jobs SET state = ?, error = ?, result = ?, exact = ?, finished_at "
                        "= ?, outcome = ?, lease_owner = NULL, lease_expires = 0 WHERE id = ?");
    q.bind(1, std::string(proto::JobStateName(end.state)));
    q.bind(2, end.error);
    if (end.result_json.empty()) {
      q.bind(3);
    } else {
      q.bind(3, end.result_json);
    }
    if (end.exact) {
      q.bind(4, *end.exact ? 1 : 0);
    } else {
      q.bind(4);
    }
    q.bind(5, end.finished_at);
    if (end.outcome_json.empty()) {
      q.bind(6);
    } else {
      q.bind(6, end.outcome_json);
    }
    q.bind(7, lease.job_id);
    q.exec();
    RecordEnd(db, lease.job_id, UnixNow(), kLeaseFinished);
    // A finished job is never resumed: its checkpoint is dead weight.
    SQLite::Statement d(db, "DELETE FROM checkpoints WHERE job_id = ?");
    d.bind(1, lease.job_id);
    d.exec();
    tx.commit();
  });
}

void SqliteStore::RewindTo(const Lease& lease, int generation) {
  Run([&](SQLite::Database& db) {
    SQLite::Transaction tx(db, SQLite::TransactionBehavior::IMMEDIATE);
    CheckLease(db, lease);
    for (const char* table : {"trace", "improvements"}) {
      SQLite::Statement q(
          db, std::string("DELETE FROM ") + table + " WHERE job_id = ? AND generation > ?");
      q.bind(1, lease.job_id);
      q.bind(2, generation);
      q.exec();
    }
    tx.commit();
  });
}

JobStore::CancelOutcome SqliteStore::RequestCancel(std::int64_t id) {
  return Run([&](SQLite::Database& db) {
    SQLite::Transaction tx(db, SQLite::TransactionBehavior::IMMEDIATE);
    SQLite::Statement queued(db,
                             "UPDATE jobs SET state = 'cancelled', finished_at = ? WHERE id = ? "
                             "AND state = 'queued'");
    queued.bind(1, UnixNow());
    queued.bind(2, id);
    if (queued.exec() > 0) {
      tx.commit();
      return CancelOutcome::kCancelled;
    }
    SQLite::Statement running(
        db,
        "UPDATE jobs SET cancel_requested = 1 WHERE id = ? AND state IN ('running', 'preparing')");
    running.bind(1, id);
    const bool requested = running.exec() > 0;
    tx.commit();
    return requested ? CancelOutcome::kRequested : CancelOutcome::kNotActive;
  });
}

std::optional<std::string> SqliteStore::GetResult(std::int64_t id) {
  return Read([&](SQLite::Database& db) -> std::optional<std::string> {
    SQLite::Statement q(db, "SELECT result FROM jobs WHERE id = ?");
    q.bind(1, id);
    if (!q.executeStep() || q.getColumn(0).isNull()) return std::nullopt;
    return q.getColumn(0).getString();
  });
}

std::vector<TraceRow> SqliteStore::GetTrace(std::int64_t id, int after, int limit) {
  return Read([&](SQLite::Database& db) {
    SQLite::Statement q(db, "SELECT " SF_TRACE_COLUMNS
                            " FROM trace WHERE job_id = ? AND generation > ? ORDER BY generation "
                            "LIMIT ?");
    q.bind(1, id);
    q.bind(2, after);
    q.bind(3, limit);
    std::vector<TraceRow> trace;
    while (q.executeStep()) trace.push_back(rows::TraceRowOf(SqliteRow{q}));
    return trace;
  });
}

std::vector<Improvement> SqliteStore::GetImprovements(std::int64_t id,
                                                      const ImprovementPage& page) {
  return Read([&](SQLite::Database& db) {
    SQLite::Statement q(db, std::string("SELECT " SF_IMPROVEMENT_COLUMNS
                                        " FROM improvements i JOIN jobs j ON j.id = i.job_id "
                                        "WHERE i.job_id = ? AND i.generation > ? ") +
                                (page.last ? "ORDER BY i.generation DESC LIMIT 1"
                                           : "ORDER BY i.generation LIMIT ?"));
    q.bind(1, id);
    q.bind(2, page.last ? -1 : page.after);
    if (!page.last) q.bind(3, page.limit > 0 ? page.limit : -1);  // (-1: no limit)
    std::vector<Improvement> out;
    while (q.executeStep()) out.push_back(rows::ImprovementOf(SqliteRow{q}));
    return out;
  });
}

std::optional<std::string> SqliteStore::GetCheckpoint(std::int64_t id) {
  return Read([&](SQLite::Database& db) -> std::optional<std::string> {
    SQLite::Statement q(db, "SELECT state FROM checkpoints WHERE job_id = ?");
    q.bind(1, id);
    if (!q.executeStep()) return std::nullopt;
    return q.getColumn(0).getString();
  });
}

std::vector<LeaseRecord> SqliteStore::LeaseHistory(std::int64_t id) {
  return Read([&](SQLite::Database& db) {
    SQLite::Statement q(db,
                        "SELECT " SF_LEASE_COLUMNS " FROM leases WHERE job_id = ? ORDER BY epoch");
    q.bind(1, id);
    std::vector<LeaseRecord> out;
    while (q.executeStep()) out.push_back(rows::LeaseOf(SqliteRow{q}));
    return out;
  });
}

bool SqliteStore::DeleteJob(std::int64_t id) {
  return Run([&](SQLite::Database& db) {
    SQLite::Statement q(
        db, "DELETE FROM jobs WHERE id = ? AND state IN ('succeeded', 'failed', 'cancelled')");
    q.bind(1, id);
    return q.exec() > 0;
  });
}

}  // namespace springfit::server
