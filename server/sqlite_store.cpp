#include "server/sqlite_store.h"

#include <bit>
#include <stdexcept>

#include <SQLiteCpp/SQLiteCpp.h>

#include "engine/search/fitness_cache.h"
#include "proto/search_codec.h"

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
  genome BLOB NOT NULL,              -- packed 8 genes per byte (FitnessCache::Key)
  PRIMARY KEY (job_id, generation)
);
CREATE TABLE checkpoints (
  job_id INTEGER PRIMARY KEY REFERENCES jobs (id) ON DELETE CASCADE,
  generation INTEGER NOT NULL,
  state BLOB NOT NULL                -- server/checkpoint_codec.h
);
)sql",
};
constexpr int kMigrationCount = static_cast<int>(std::size(kMigrations));
static_assert(kMigrationCount == SqliteStore::kSchemaVersion);

constexpr const char* kJobColumns =
    "id, label, priority, seed, idempotency_key, state, error, scene_name, genes, strategy, "
    "max_generations, "
    "created_at, started_at, finished_at, progress, checkpoint_generation, exact";

JobRecord ReadJob(SQLite::Statement& q) {
  JobRecord j;
  j.id = q.getColumn(0).getInt64();
  j.label = q.getColumn(1).getString();
  j.priority = q.getColumn(2).getInt();
  j.seed = std::bit_cast<std::uint64_t>(q.getColumn(3).getInt64());
  if (!q.getColumn(4).isNull()) j.idempotency_key = q.getColumn(4).getString();
  j.state = proto::ParseJobState(q.getColumn(5).getString()).value_or(JobState::kFailed);
  j.error = q.getColumn(6).getString();
  j.scene_name = q.getColumn(7).getString();
  j.genes = q.getColumn(8).getInt();
  j.strategy = q.getColumn(9).getString();
  j.max_generations = q.getColumn(10).getInt();
  j.created_at = q.getColumn(11).getDouble();
  j.started_at = q.getColumn(12).getDouble();
  j.finished_at = q.getColumn(13).getDouble();
  if (!q.getColumn(14).isNull())
    j.progress = proto::TraceRowFromJson(proto::ParseJson(q.getColumn(14).getString()), "progress");
  j.checkpoint_generation = q.getColumn(15).getInt();
  if (!q.getColumn(16).isNull()) j.exact = q.getColumn(16).getInt() != 0;
  return j;
}

void BindCount(SQLite::Statement& q, int index, int count) {
  if (count < 0) {
    q.bind(index);
  } else {
    q.bind(index, count);
  }
}
std::optional<int> CountOrNull(const SQLite::Column& c) {
  return c.isNull() ? std::nullopt : std::optional<int>(c.getInt());
}

void BindBlob(SQLite::Statement& q, int index, const std::string& bytes) {
  if (bytes.size() > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
    throw std::runtime_error("store: a blob over 2 GiB");
  }
  q.bind(index, bytes.data(), static_cast<int>(bytes.size()));
}

}  // namespace

SqliteStore::SqliteStore(const std::string& path) {
  try {
    db_ = std::make_unique<SQLite::Database>(path, SQLite::OPEN_READWRITE | SQLite::OPEN_CREATE);
    db_->setBusyTimeout(5000);
    db_->exec("PRAGMA journal_mode = WAL");
    db_->exec("PRAGMA synchronous = FULL");
    db_->exec("PRAGMA foreign_keys = ON");
    Migrate();
  } catch (const SQLite::Exception& e) {
    throw std::runtime_error("cannot open the database " + path + ": " + e.what());
  }
}

SqliteStore::~SqliteStore() = default;

int SqliteStore::schema_version() {
  std::lock_guard lock(mutex_);
  return db_->execAndGet("PRAGMA user_version").getInt();
}

void SqliteStore::Migrate() {
  SQLite::Transaction tx(*db_);
  const int version = db_->execAndGet("PRAGMA user_version").getInt();
  if (version > kSchemaVersion) {
    throw std::runtime_error("the database has schema version " + std::to_string(version) +
                             ", newer than this springfitd's " + std::to_string(kSchemaVersion));
  }
  for (int v = version; v < kSchemaVersion; ++v) db_->exec(kMigrations[v]);
  db_->exec("PRAGMA user_version = " + std::to_string(kSchemaVersion));
  tx.commit();
}

JobStore::Created SqliteStore::CreateJob(const NewJob& job) {
  std::lock_guard lock(mutex_);
  SQLite::Transaction tx(*db_);
  const JobRecord& r = job.record;
  if (!r.idempotency_key.empty()) {
    SQLite::Statement q(
        *db_, std::string("SELECT ") + kJobColumns + " FROM jobs WHERE idempotency_key = ?");
    q.bind(1, r.idempotency_key);
    if (q.executeStep()) return {ReadJob(q), false};
  }
  SQLite::Statement insert(
      *db_,
      "INSERT INTO jobs (label, priority, seed, idempotency_key, state, scene_name, genes, "
      "strategy, max_generations, created_at, scene) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
  insert.bind(1, r.label);
  insert.bind(2, r.priority);
  insert.bind(3, std::bit_cast<std::int64_t>(r.seed));
  if (r.idempotency_key.empty()) {
    insert.bind(4);
  } else {
    insert.bind(4, r.idempotency_key);
  }
  insert.bind(5, std::string(proto::JobStateName(JobState::kQueued)));
  insert.bind(6, r.scene_name);
  insert.bind(7, r.genes);
  insert.bind(8, r.strategy);
  insert.bind(9, r.max_generations);
  insert.bind(10, r.created_at);
  insert.bind(11, job.scene_json);
  insert.exec();
  JobRecord created = r;
  created.id = db_->getLastInsertRowid();
  created.state = JobState::kQueued;
  tx.commit();
  return {created, true};
}

std::optional<JobRecord> SqliteStore::GetJob(std::int64_t id) {
  std::lock_guard lock(mutex_);
  SQLite::Statement q(*db_, std::string("SELECT ") + kJobColumns + " FROM jobs WHERE id = ?");
  q.bind(1, id);
  if (!q.executeStep()) return std::nullopt;
  return ReadJob(q);
}

std::optional<std::string> SqliteStore::GetScene(std::int64_t id) {
  std::lock_guard lock(mutex_);
  SQLite::Statement q(*db_, "SELECT scene FROM jobs WHERE id = ?");
  q.bind(1, id);
  if (!q.executeStep()) return std::nullopt;
  return q.getColumn(0).getString();
}

JobPage SqliteStore::ListJobs(const JobFilter& f) {
  std::lock_guard lock(mutex_);
  std::string sql = std::string("SELECT ") + kJobColumns + " FROM jobs WHERE id > ?";
  if (f.state) sql += " AND state = ?";
  if (f.label) sql += " AND label = ?";
  sql += " ORDER BY id LIMIT ?";
  SQLite::Statement q(*db_, sql);
  int i = 1;
  q.bind(i++, f.after_id);
  if (f.state) q.bind(i++, std::string(proto::JobStateName(*f.state)));
  if (f.label) q.bind(i++, *f.label);
  q.bind(i++, f.limit + 1);  // one more tells whether there is a next page
  JobPage page;
  while (q.executeStep()) page.jobs.push_back(ReadJob(q));
  if (static_cast<int>(page.jobs.size()) > f.limit) {
    page.jobs.pop_back();
    page.next_cursor = page.jobs.back().id;
  }
  return page;
}

std::vector<JobRecord> SqliteStore::UnfinishedJobs() {
  std::lock_guard lock(mutex_);
  SQLite::Statement q(
      *db_, std::string("SELECT ") + kJobColumns +
                " FROM jobs WHERE state IN ('queued', 'running') ORDER BY priority DESC, id");
  std::vector<JobRecord> jobs;
  while (q.executeStep()) jobs.push_back(ReadJob(q));
  return jobs;
}

int SqliteStore::CountQueued() {
  std::lock_guard lock(mutex_);
  return db_->execAndGet("SELECT count(*) FROM jobs WHERE state = 'queued'").getInt();
}

void SqliteStore::MarkRunning(std::int64_t id, double started_at) {
  std::lock_guard lock(mutex_);
  SQLite::Statement q(*db_, "UPDATE jobs SET state = 'running', started_at = ? WHERE id = ?");
  q.bind(1, started_at);
  q.bind(2, id);
  q.exec();
}

void SqliteStore::SaveProgress(std::int64_t id, const ProgressBatch& b) {
  std::lock_guard lock(mutex_);
  SQLite::Transaction tx(*db_);
  if (!b.trace.empty()) {
    SQLite::Statement q(
        *db_,
        "INSERT OR REPLACE INTO trace (job_id, generation, wall_seconds, evaluations, cache_hits, "
        "best_cost, best_normalized_error, mean_cost, missing, extra) VALUES (?, ?, ?, ?, ?, ?, ?, "
        "?, ?, ?)");
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
    SQLite::Statement q(*db_,
                        "INSERT OR REPLACE INTO improvements (job_id, generation, wall_seconds, "
                        "cost, normalized_error, "
                        "missing, extra, genome) VALUES (?, ?, ?, ?, ?, ?, ?, ?)");
    for (const Improvement& m : b.improvements) {
      q.bind(1, id);
      q.bind(2, m.generation);
      q.bind(3, m.wall_seconds);
      q.bind(4, m.cost);
      q.bind(5, m.normalized_error);
      BindCount(q, 6, m.missing);
      BindCount(q, 7, m.extra);
      BindBlob(q, 8, FitnessCache::Key(m.genome));
      q.exec();
      q.reset();
    }
  }
  if (b.latest) {
    SQLite::Statement q(*db_, "UPDATE jobs SET progress = ? WHERE id = ?");
    q.bind(1, proto::TraceRowToJson(*b.latest).dump());
    q.bind(2, id);
    q.exec();
  }
  if (b.checkpoint) {
    SQLite::Statement q(
        *db_, "INSERT OR REPLACE INTO checkpoints (job_id, generation, state) VALUES (?, ?, ?)");
    q.bind(1, id);
    q.bind(2, b.checkpoint_generation);
    BindBlob(q, 3, *b.checkpoint);
    q.exec();
    SQLite::Statement u(*db_, "UPDATE jobs SET checkpoint_generation = ? WHERE id = ?");
    u.bind(1, b.checkpoint_generation);
    u.bind(2, id);
    u.exec();
  }
  tx.commit();
}

void SqliteStore::MarkFinished(std::int64_t id, JobState state, const std::string& error,
                               const std::string& result_json, std::optional<bool> exact,
                               double finished_at) {
  std::lock_guard lock(mutex_);
  SQLite::Transaction tx(*db_);
  SQLite::Statement q(
      *db_,
      "UPDATE jobs SET state = ?, error = ?, result = ?, exact = ?, finished_at = ? WHERE id = ?");
  q.bind(1, std::string(proto::JobStateName(state)));
  q.bind(2, error);
  if (result_json.empty()) {
    q.bind(3);
  } else {
    q.bind(3, result_json);
  }
  if (exact) {
    q.bind(4, *exact ? 1 : 0);
  } else {
    q.bind(4);
  }
  q.bind(5, finished_at);
  q.bind(6, id);
  q.exec();
  // A finished job is never resumed: its checkpoint is dead weight.
  SQLite::Statement d(*db_, "DELETE FROM checkpoints WHERE job_id = ?");
  d.bind(1, id);
  d.exec();
  tx.commit();
}

std::optional<std::string> SqliteStore::GetResult(std::int64_t id) {
  std::lock_guard lock(mutex_);
  SQLite::Statement q(*db_, "SELECT result FROM jobs WHERE id = ?");
  q.bind(1, id);
  if (!q.executeStep() || q.getColumn(0).isNull()) return std::nullopt;
  return q.getColumn(0).getString();
}

std::vector<TraceRow> SqliteStore::GetTrace(std::int64_t id, int after, int limit) {
  std::lock_guard lock(mutex_);
  SQLite::Statement q(
      *db_,
      "SELECT generation, wall_seconds, evaluations, cache_hits, best_cost, best_normalized_error, "
      "mean_cost, missing, extra FROM trace WHERE job_id = ? AND generation > ? ORDER BY "
      "generation LIMIT ?");
  q.bind(1, id);
  q.bind(2, after);
  q.bind(3, limit);
  std::vector<TraceRow> rows;
  while (q.executeStep()) {
    TraceRow r;
    r.generation = q.getColumn(0).getInt();
    r.wall_seconds = q.getColumn(1).getDouble();
    r.evaluations = q.getColumn(2).getInt64();
    r.cache_hits = q.getColumn(3).getInt64();
    r.best_cost = q.getColumn(4).getDouble();
    r.best_normalized_error = q.getColumn(5).getDouble();
    r.mean_cost = q.getColumn(6).getDouble();
    r.missing = CountOrNull(q.getColumn(7)).value_or(-1);
    r.extra = CountOrNull(q.getColumn(8)).value_or(-1);
    rows.push_back(r);
  }
  return rows;
}

std::vector<Improvement> SqliteStore::GetImprovements(std::int64_t id) {
  std::lock_guard lock(mutex_);
  SQLite::Statement q(*db_,
                      "SELECT i.generation, i.wall_seconds, i.cost, i.normalized_error, i.missing, "
                      "i.extra, i.genome, "
                      "j.genes FROM improvements i JOIN jobs j ON j.id = i.job_id WHERE i.job_id = "
                      "? ORDER BY i.generation");
  q.bind(1, id);
  std::vector<Improvement> out;
  while (q.executeStep()) {
    Improvement m;
    m.generation = q.getColumn(0).getInt();
    m.wall_seconds = q.getColumn(1).getDouble();
    m.cost = q.getColumn(2).getDouble();
    m.normalized_error = q.getColumn(3).getDouble();
    m.missing = CountOrNull(q.getColumn(4)).value_or(-1);
    m.extra = CountOrNull(q.getColumn(5)).value_or(-1);
    m.genome = FitnessCache::Unpack(q.getColumn(6).getString(), q.getColumn(7).getInt());
    out.push_back(std::move(m));
  }
  return out;
}

std::optional<std::string> SqliteStore::GetCheckpoint(std::int64_t id) {
  std::lock_guard lock(mutex_);
  SQLite::Statement q(*db_, "SELECT state FROM checkpoints WHERE job_id = ?");
  q.bind(1, id);
  if (!q.executeStep()) return std::nullopt;
  return q.getColumn(0).getString();
}

void SqliteStore::RewindTo(std::int64_t id, int generation) {
  std::lock_guard lock(mutex_);
  SQLite::Transaction tx(*db_);
  for (const char* table : {"trace", "improvements"}) {
    SQLite::Statement q(
        *db_, std::string("DELETE FROM ") + table + " WHERE job_id = ? AND generation > ?");
    q.bind(1, id);
    q.bind(2, generation);
    q.exec();
  }
  tx.commit();
}

bool SqliteStore::DeleteJob(std::int64_t id) {
  std::lock_guard lock(mutex_);
  SQLite::Statement q(*db_, "DELETE FROM jobs WHERE id = ?");
  q.bind(1, id);
  return q.exec() > 0;
}

}  // namespace springfit::server
