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
#include <string>

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

// A trace row's columns (table trace), in the order TraceRowOf reads them.
#define SF_TRACE_COLUMNS                                                                  \
  "generation, wall_seconds, evaluations, cache_hits, best_cost, best_normalized_error, " \
  "mean_cost, missing, extra"

// An improvement's columns (table improvements as i, joined to its job as j for the genome's
// length), in the order ImprovementOf reads them.
#define SF_IMPROVEMENT_COLUMNS                                                               \
  "i.generation, i.wall_seconds, i.cost, i.normalized_error, i.missing, i.extra, i.genome, " \
  "j.genes"

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

}  // namespace springfit::server::rows
