// The job and trace rows the store tests write: a seed above int64's range (stored as its
// bits), a missing count at generation 0, an infinite mean cost at generation 2.
#pragma once
#include <limits>
#include <string>

#include "server/store/job_store.h"

namespace springfit::server {

inline NewJob StoreTestJob(const std::string& label, int priority = 0,
                           const std::string& key = "") {
  NewJob j;
  j.record.label = label;
  j.record.priority = priority;
  j.record.seed = 0xfedcba9876543210ULL;  // above int64's range: stored as its bits
  j.record.idempotency_key = key;
  // (Move-assigned: GCC 12 warns wrongly about the copy of a short literal, -Wrestrict.)
  j.record.scene_name = std::string("s");
  j.record.genes = 12;
  j.record.strategy = "default";
  j.record.max_generations = 100;
  j.record.created_at = 1.5e9;
  j.scene_json = std::string(R"({"name":"s"})");
  return j;
}

inline TraceRow StoreTestRow(int generation, double error) {
  TraceRow r;
  r.generation = generation;
  r.wall_seconds = 0.1 * generation + 1e-9;
  r.evaluations = 10 * (generation + 1);
  r.best_cost = error * 2;
  r.best_normalized_error = error;
  r.mean_cost = generation == 2 ? std::numeric_limits<double>::infinity() : error * 3;
  r.missing = generation == 0 ? -1 : 3;
  r.extra = 1;
  return r;
}

}  // namespace springfit::server
