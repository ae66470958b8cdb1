#include "server/store/job_store.h"

#include <algorithm>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "engine/api/input_error.h"
#include "proto/json_reader.h"
#include "proto/outcome_codec.h"
#include "proto/search_codec.h"
#include "server/store/store_rows.h"

namespace springfit::server {

namespace {
thread_local double t_store_deadline = 0.0;
}  // namespace

ScopedStoreDeadline::ScopedStoreDeadline(double seconds) : previous_(t_store_deadline) {
  t_store_deadline = previous_ > 0.0 ? std::min(previous_, seconds) : seconds;
}

ScopedStoreDeadline::~ScopedStoreDeadline() {
  t_store_deadline = previous_;
}

double ScopedStoreDeadline::Current() {
  return t_store_deadline;
}

StoreCorrupt::StoreCorrupt(const QuarantinedJob& quarantined)
    : std::runtime_error("job " + std::to_string(quarantined.job_id) +
                         " is quarantined (quarantine incident " +
                         std::to_string(quarantined.incident) + "): " + quarantined.reason),
      incident_(quarantined.incident) {}

JobState StoredJobState(std::int64_t job_id, const std::string& text) {
  if (const auto state = proto::ParseJobState(text)) return *state;
  throw StoreCorrupt("job " + std::to_string(job_id) + ": the store holds the unknown state '" +
                     text + "'");
}

TraceRow StoredProgress(std::int64_t job_id, const std::string& text) {
  try {
    return proto::TraceRowFromJson(proto::ParseJson(text), "progress");
  } catch (const std::exception& e) {
    throw StoreCorrupt("job " + std::to_string(job_id) +
                       ": the store's progress column is not a trace row (" + e.what() + ")");
  }
}

Outcome StoredOutcome(std::int64_t job_id, const std::string& text) {
  try {
    return proto::OutcomeFromJson(proto::ParseJson(text), "outcome");
  } catch (const std::exception& e) {
    throw StoreCorrupt("job " + std::to_string(job_id) +
                       ": the store's outcome column is not a verdict (" + e.what() + ")");
  }
}

std::optional<std::string> LeaseOverlap(const std::vector<LeaseRecord>& history) {
  for (std::size_t i = 1; i < history.size(); ++i) {
    const LeaseRecord& before = history[i - 1];
    const LeaseRecord& claim = history[i];
    // (A lease ended by its holder ends there; one that lapsed, at its last expiry.)
    const double held_until = before.ended_at ? *before.ended_at : before.expires_at;
    if (claim.epoch <= before.epoch || claim.granted_at < held_until) {
      return fmt::format("claim {} by {} at {:.3f} while claim {} by {} held it until {:.3f}{}",
                         claim.epoch, claim.owner, claim.granted_at, before.epoch, before.owner,
                         held_until, before.ended_at ? " (" + before.ended + ")" : "");
    }
  }
  return std::nullopt;
}

std::optional<QuarantinedJob> rows::Announced(const std::optional<Quarantining>& q) {
  if (!q) return std::nullopt;
  if (q->first) {
    spdlog::error(
        "job {} quarantined (quarantine incident {}): {}; it is never claimed, the other jobs go "
        "on; repair or delete its row in the store",
        q->job.job_id, q->job.incident, q->job.reason);
  }
  return q->job;
}

}  // namespace springfit::server
