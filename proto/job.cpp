#include "proto/job.h"

#include <cmath>

#include <array>
#include <utility>

#include <fmt/format.h>

#include "engine/api/input_error.h"
#include "proto/names.h"
#include "proto/outcome_codec.h"
#include "proto/search_codec.h"

namespace springfit::proto {
namespace {

constexpr std::array<std::pair<JobState, std::string_view>, 6> kStateNames{{
    {JobState::kPreparing, "preparing"},
    {JobState::kQueued, "queued"},
    {JobState::kRunning, "running"},
    {JobState::kSucceeded, "succeeded"},
    {JobState::kFailed, "failed"},
    {JobState::kCancelled, "cancelled"},
}};

// Times of events that have not happened yet are null.
Json TimeOrNull(double t) {
  return t > 0.0 ? Json(t) : Json(nullptr);
}
double ReadTime(const Json& j, const std::string& path) {
  return j.is_null() ? 0.0 : ReadNumber(j, path);
}

}  // namespace

std::string_view JobStateName(JobState state) {
  for (const auto& [s, name] : kStateNames) {
    if (s == state) return name;
  }
  return "unknown";
}

std::vector<JobState> AllJobStates() {
  std::vector<JobState> states;
  for (const auto& [s, name] : kStateNames) states.push_back(s);
  return states;
}

std::optional<JobState> ParseJobState(std::string_view name) {
  for (const auto& [s, n] : kStateNames) {
    if (n == name) return s;
  }
  return std::nullopt;
}

bool ProgressCountsSteps(std::string_view strategy) {
  return strategy == StrategyName(Strategy::kContinuous);
}

std::string JobErrorText(const JobRecord& job) {
  const auto text = [](double e) {
    if (!std::isfinite(e)) return std::string("-");
    return fmt::format("{:.3g}", e);
  };
  // (A linear response: E as simulated, as the headline gives it first.)
  if (job.outcome) {
    const std::optional<double>& e = job.outcome->simulated_rms_error
                                         ? job.outcome->simulated_rms_error
                                         : job.outcome->rms_error;
    return e ? text(*e) : "-";
  }
  return job.progress ? text(std::sqrt(job.progress->best_normalized_error)) + "~" : "-";
}

std::string ClockText(double seconds) {
  if (!(seconds >= 0.0) || !std::isfinite(seconds)) return "-";
  const long long total = std::llround(seconds);
  if (total < 3600) return fmt::format("{}:{:02}", total / 60, total % 60);
  return fmt::format("{}:{:02}:{:02}", total / 3600, total / 60 % 60, total % 60);
}

Json JobToJson(const JobRecord& job) {
  Json j;
  j["job_id"] = job.id;
  j["label"] = job.label;
  j["priority"] = job.priority;
  j["seed"] = job.seed;
  j["idempotency_key"] = job.idempotency_key.empty() ? Json(nullptr) : Json(job.idempotency_key);
  j["state"] = JobStateName(job.state);
  j["error"] = job.error.empty() ? Json(nullptr) : Json(job.error);
  j["scene"] = job.scene_name;
  j["genes"] = job.genes;
  j["strategy"] = job.strategy;
  j["max_generations"] = job.max_generations;
  j["created_at"] = TimeOrNull(job.created_at);
  j["started_at"] = TimeOrNull(job.started_at);
  j["finished_at"] = TimeOrNull(job.finished_at);
  j["progress"] = job.progress ? TraceRowToJson(*job.progress) : Json(nullptr);
  j["checkpoint_generation"] =
      job.checkpoint_generation >= 0 ? Json(job.checkpoint_generation) : Json(nullptr);
  j["exact"] = job.exact ? Json(*job.exact) : Json(nullptr);
  j["outcome"] = job.outcome ? OutcomeToJson(*job.outcome) : Json(nullptr);
  return j;
}

JobRecord JobFromJson(const Json& j) {
  // A reader of what a server wrote: members it does not know (a newer server's) are ignored,
  // as proto/RPC.md says a client must (unlike a scene, whose unknown fields are errors).
  const std::string path = "result";
  auto at = [&](const char* key) -> const Json& { return RequiredMember(j, path, key); };
  auto sub = [&](const char* key) { return JoinPath(path, key); };
  JobRecord job;
  job.id = static_cast<std::int64_t>(ReadUint64(at("job_id"), sub("job_id")));
  job.label = ReadString(at("label"), sub("label"));
  job.priority = ReadInt(at("priority"), sub("priority"));
  job.seed = ReadUint64(at("seed"), sub("seed"));
  if (!at("idempotency_key").is_null())
    job.idempotency_key = ReadString(at("idempotency_key"), sub("idempotency_key"));
  const std::string state = ReadString(at("state"), sub("state"));
  const auto parsed = ParseJobState(state);
  if (!parsed) throw InputError(sub("state"), "unknown job state '" + state + "'");
  job.state = *parsed;
  if (!at("error").is_null()) job.error = ReadString(at("error"), sub("error"));
  job.scene_name = ReadString(at("scene"), sub("scene"));
  job.genes = ReadInt(at("genes"), sub("genes"));
  job.strategy = ReadString(at("strategy"), sub("strategy"));
  job.max_generations = ReadInt(at("max_generations"), sub("max_generations"));
  job.created_at = ReadTime(at("created_at"), sub("created_at"));
  job.started_at = ReadTime(at("started_at"), sub("started_at"));
  job.finished_at = ReadTime(at("finished_at"), sub("finished_at"));
  if (!at("progress").is_null()) job.progress = TraceRowFromJson(at("progress"), sub("progress"));
  if (!at("checkpoint_generation").is_null()) {
    job.checkpoint_generation = ReadInt(at("checkpoint_generation"), sub("checkpoint_generation"));
  }
  if (!at("exact").is_null()) {
    if (!at("exact").is_boolean()) throw InputError(sub("exact"), "expected a boolean");
    job.exact = at("exact").get<bool>();
  }
  // (Absent from an older daemon's answer.)
  if (j.contains("outcome") && !j["outcome"].is_null())
    job.outcome = OutcomeFromJson(j["outcome"], sub("outcome"));
  return job;
}

}  // namespace springfit::proto
