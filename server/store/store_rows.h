// The stores' rows, written once for both SQL dialects: the columns every SELECT of a job, a
// trace row or an improvement lists, and how such a row becomes its struct. SqliteStore and
// PostgresStore each adapt their own row to the `Row` these read, which answers, for the
// column at a 0-based index:
//   bool Null(i); std::int64_t Int64(i); int Int(i); double Double(i); bool Bool(i);
//   std::string Text(i); std::string Blob(i);
// (The schemas stay one per dialect: each is its store's migration history, which databases
// already written record by version.)
#pragma once

#include <bit>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "engine/api/checkpoint.h"
#include "engine/api/result.h"
#include "proto/job.h"
#include "server/store/job_store.h"

namespace springfit::server::rows {

// A job's columns, in the order JobOf reads them.
#define SF_JOB_COLUMNS                                                                      \
  "id, label, priority, seed, idempotency_key, state, error, scene_name, genes, strategy, " \
  "max_generations, created_at, started_at, finished_at, progress, checkpoint_generation, " \
  "exact, outcome"
inline constexpr int kJobColumnCount = 18;

// A job's columns with its quarantine's (null unless it is quarantined), in the order
// ListedJobOf reads them, from SF_JOBS_LISTED.
#define SF_LISTED_COLUMNS \
  SF_JOB_COLUMNS ", incident, job_id, reason, quarantined_at, previous_state"
#define SF_JOBS_LISTED "jobs LEFT JOIN quarantine ON job_id = id"

// A trace row's columns (table trace), in the order TraceRowOf reads them.
#define SF_TRACE_COLUMNS                                                                  \
  "generation, wall_seconds, evaluations, cache_hits, best_cost, best_normalized_error, " \
  "mean_cost, missing, extra"

// An improvement's columns (table improvements as i, joined to its job as j for the genome's
// length), in the order ImprovementOf reads them.
#define SF_IMPROVEMENT_COLUMNS                                                               \
  "i.generation, i.wall_seconds, i.cost, i.normalized_error, i.missing, i.extra, i.genome, " \
  "j.genes"

// A lease history row's columns (table leases), in the order LeaseOf reads them.
#define SF_LEASE_COLUMNS "epoch, owner, granted_at, expires_at, ended_at, ended"

// A count the store keeps as NULL when unknown, -1 in memory.
template <typename Row>
int CountOrUnknown(const Row& r, int i) {
  return r.Null(i) ? -1 : r.Int(i);
}

template <typename Row>
JobRecord JobOf(const Row& r) {
  JobRecord j;
  j.id = r.Int64(0);
  j.label = r.Text(1);
  j.priority = r.Int(2);
  j.seed = std::bit_cast<std::uint64_t>(r.Int64(3));  // the uint64 seed's bits
  if (!r.Null(4)) j.idempotency_key = r.Text(4);
  j.state = StoredJobState(j.id, r.Text(5));
  j.error = r.Text(6);
  j.scene_name = r.Text(7);
  j.genes = r.Int(8);
  j.strategy = r.Text(9);
  j.max_generations = r.Int(10);
  j.created_at = r.Double(11);
  j.started_at = r.Double(12);
  j.finished_at = r.Double(13);
  if (!r.Null(14)) j.progress = StoredProgress(j.id, r.Text(14));
  j.checkpoint_generation = r.Int(15);
  if (!r.Null(16)) j.exact = r.Bool(16);
  if (!r.Null(17)) j.outcome = StoredOutcome(j.id, r.Text(17));
  return j;
}

// A job's row as a listing reads it: the job, or its quarantine, or else the damage that
// makes it unreadable (StoreCorrupt's message), which the store is to quarantine.
struct ListedJob {
  std::int64_t id = 0;
  std::string stored_state;  // the state column's text, whatever it holds
  std::optional<JobRecord> job;
  std::optional<QuarantinedJob> quarantined;
  std::string damage;
};

template <typename Row>
ListedJob ListedJobOf(const Row& r) {
  ListedJob listed;
  listed.id = r.Int64(0);
  listed.stored_state = r.Text(5);
  if (!r.Null(kJobColumnCount)) {
    QuarantinedJob& q = listed.quarantined.emplace();
    q.incident = r.Int64(kJobColumnCount);
    q.job_id = r.Int64(kJobColumnCount + 1);
    q.reason = r.Text(kJobColumnCount + 2);
    q.quarantined_at = r.Double(kJobColumnCount + 3);
    q.previous_state = r.Text(kJobColumnCount + 4);
    return listed;
  }
  try {
    listed.job = JobOf(r);
  } catch (const StoreCorrupt& e) {
    listed.damage = e.what();
  }
  return listed;
}

// A job's quarantine, and whether this call set it (and is to log it, once committed).
struct Quarantining {
  QuarantinedJob job;
  bool first = false;
};

// In a write transaction, with `row` the job's row read again there: the job's quarantine,
// made by `insert(row)` when the row is still damaged; nothing when it is gone or readable
// again.
template <typename Insert>
std::optional<Quarantining> QuarantineIfDamaged(const std::optional<ListedJob>& row,
                                                Insert&& insert) {
  if (!row || row->job) return std::nullopt;
  if (row->quarantined) return Quarantining{*row->quarantined, false};
  return Quarantining{insert(*row), true};
}

// A quarantine, committed: logged (one line) when this call set it. Returns its job.
std::optional<QuarantinedJob> Announced(const std::optional<Quarantining>& q);

// The job of a listed row, or StoreCorrupt naming its quarantine: `quarantine(id)` (the
// store's) quarantines a damaged row, returning its QuarantinedJob when it still is.
template <typename Quarantine>
JobRecord ReadableJob(const ListedJob& row, Quarantine&& quarantine) {
  if (row.job) return *row.job;
  if (row.quarantined) throw StoreCorrupt(*row.quarantined);
  if (const std::optional<QuarantinedJob> q = quarantine(row.id)) throw StoreCorrupt(*q);
  throw StoreCorrupt(row.damage);  // (repaired since: read again)
}

// A listing's rows (up to `limit` + 1, in the listing's order) as a page: the damaged rows
// quarantined through `quarantine`, and shown so with those quarantined before.
template <typename Quarantine>
JobPage PageOf(std::vector<ListedJob> rows, int limit, Quarantine&& quarantine) {
  JobPage page;
  if (static_cast<int>(rows.size()) > limit) {
    rows.resize(static_cast<std::size_t>(limit));
    page.next_cursor = rows.back().id;
  }
  for (ListedJob& row : rows) {
    if (row.job) {
      page.jobs.push_back(std::move(*row.job));
    } else if (row.quarantined) {
      page.quarantined.push_back(*row.quarantined);
    } else if (const std::optional<QuarantinedJob> q = quarantine(row.id)) {
      page.quarantined.push_back(*q);
    }  // (repaired since it was read: on the next listing)
  }
  return page;
}

// The readable jobs of `rows`, the damaged ones quarantined through `quarantine`.
template <typename Quarantine>
std::vector<JobRecord> ReadableJobs(std::vector<ListedJob> rows, Quarantine&& quarantine) {
  return PageOf(std::move(rows), std::numeric_limits<int>::max(), quarantine).jobs;
}

template <typename Row>
TraceRow TraceRowOf(const Row& r) {
  TraceRow t;
  t.generation = r.Int(0);
  t.wall_seconds = r.Double(1);
  t.evaluations = r.Int64(2);
  t.cache_hits = r.Int64(3);
  t.best_cost = r.Double(4);
  t.best_normalized_error = r.Double(5);
  t.mean_cost = r.Double(6);
  t.missing = CountOrUnknown(r, 7);
  t.extra = CountOrUnknown(r, 8);
  return t;
}

template <typename Row>
Improvement ImprovementOf(const Row& r) {
  Improvement m;
  m.generation = r.Int(0);
  m.wall_seconds = r.Double(1);
  m.cost = r.Double(2);
  m.normalized_error = r.Double(3);
  m.missing = CountOrUnknown(r, 4);
  m.extra = CountOrUnknown(r, 5);
  m.genome = UnpackGenome(r.Blob(6), r.Int(7));
  return m;
}

template <typename Row>
LeaseRecord LeaseOf(const Row& r) {
  LeaseRecord l;
  l.epoch = r.Int64(0);
  l.owner = r.Text(1);
  l.granted_at = r.Double(2);
  l.expires_at = r.Double(3);
  if (!r.Null(4)) {
    l.ended_at = r.Double(4);
    l.ended = r.Text(5);
  }
  return l;
}

}  // namespace springfit::server::rows
