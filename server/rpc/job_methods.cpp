// The job methods but job.submit (server/rpc/rpc_service.h): reads (get, result, trace, scene,
// improvements, list), cancel, delete and watch.
#include "server/rpc/rpc_service.h"

#include <algorithm>
#include <chrono>
#include <limits>
#include <memory>
#include <thread>

#include <spdlog/spdlog.h>

#include "engine/api/identify.h"
#include "engine/api/input_error.h"
#include "engine/api/problem.h"
#include "engine/api/scene.h"
#include "proto/names.h"
#include "proto/rpc.h"
#include "proto/scene_codec.h"
#include "proto/search_codec.h"
#include "server/rpc/params.h"
#include "server/rpc/token.h"
#include "server/store/unix_time.h"

namespace springfit::server {
namespace rpc = proto::rpc;
using proto::Json;

namespace {

// The quarantined jobs of a job.list page that it reaches: up to its cursor, from which the
// next page goes on (newest first: the jobs before it).
Json QuarantinedToJson(const std::vector<QuarantinedJob>& quarantined,
                       const std::optional<std::int64_t>& cursor, bool newest_first) {
  Json out = Json::array();
  for (const QuarantinedJob& q : quarantined) {
    if (cursor && (newest_first ? q.job_id < *cursor : q.job_id > *cursor)) continue;
    Json row;
    row["job_id"] = q.job_id;
    row["state"] = "quarantined";
    row["incident"] = q.incident;
    row["reason"] = q.reason;
    row["quarantined_at"] = q.quarantined_at;
    row["previous_state"] = q.previous_state;
    out.push_back(std::move(row));
  }
  return out;
}

}  // namespace

JobRecord RpcService::RequireJob(const Json& params) {
  const Json& id_json = proto::RequiredMember(params, "params", "job_id");
  const std::uint64_t id = proto::ReadUint64(id_json, ParamPath("job_id"));
  std::optional<JobRecord> job;
  if (id <= static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) {
    job = store_.GetJob(static_cast<std::int64_t>(id));
  }
  if (!job) {
    Json data;
    data["job_id"] = id;
    throw rpc::RpcError(rpc::kNoSuchJob, "no such job: " + std::to_string(id), data);
  }
  if (job->state == JobState::kRunning) {
    if (auto live = scheduler_.LiveProgress(job->id)) job->progress = live;
  }
  return *job;
}

Json RpcService::JobGet(const Json& params) {
  proto::ExpectKeys(params, "params", {"job_id"});
  return proto::JobToJson(RequireJob(params));
}

Json RpcService::JobResult(const Json& params) {
  proto::ExpectKeys(params, "params", {"job_id"});
  const JobRecord job = RequireJob(params);
  const std::optional<std::string> result = store_.GetResult(job.id);
  if (!result) {
    Json data;
    data["state"] = proto::JobStateName(job.state);
    std::string why = job.state == JobState::kFailed
                          ? "job " + std::to_string(job.id) + " failed: " + job.error
                      : proto::IsFinal(job.state)
                          ? "job " + std::to_string(job.id) + " was cancelled before it ran"
                          : "job " + std::to_string(job.id) + " is " +
                                std::string(proto::JobStateName(job.state)) + "; no result yet";
    throw rpc::RpcError(rpc::kWrongState, why, data);
  }
  Json j = proto::ParseJson(*result);
  j["state"] = proto::JobStateName(job.state);
  return j;
}

Json RpcService::JobTrace(const Json& params) {
  proto::ExpectKeys(params, "params", {"job_id", "after", "limit"});
  const JobRecord job = RequireJob(params);
  int after = -1;
  if (const Json* v = OptionalParam(params, "after"))
    after = proto::ReadInt(*v, ParamPath("after"));
  const int limit = ReadPageLimit(params, 1000, options_.limits.max_page);
  const std::vector<TraceRow> rows = store_.GetTrace(job.id, after, limit);
  Json j;
  j["job_id"] = job.id;
  Json list = Json::array();
  for (const TraceRow& row : rows) list.push_back(proto::TraceRowToJson(row));
  j["rows"] = std::move(list);
  j["next_after"] =
      static_cast<int>(rows.size()) == limit ? Json(rows.back().generation) : Json(nullptr);
  return j;
}

Json RpcService::JobScene(const Json& params) {
  proto::ExpectKeys(params, "params", {"job_id"});
  const JobRecord job = RequireJob(params);
  const std::optional<std::string> scene = store_.GetScene(job.id);
  if (!scene) throw std::runtime_error("job " + std::to_string(job.id) + " has no stored scene");
  Json j;
  j["job_id"] = job.id;
  j["scene"] = proto::ParseJson(*scene);
  return j;
}

Json RpcService::JobImprovements(const Json& params) {
  proto::ExpectKeys(params, "params", {"job_id", "after", "limit", "last"});
  const JobRecord job = RequireJob(params);
  // Paged as job.trace is (a genome per row: a long run's rows would pass any message limit),
  // and bounded in bytes as job.list is; `last`: the best so far alone.
  JobStore::ImprovementPage page;
  if (const Json* v = OptionalParam(params, "after"))
    page.after = proto::ReadInt(*v, ParamPath("after"));
  page.limit = ReadPageLimit(params, 1000, options_.limits.max_page);
  if (const Json* v = OptionalParam(params, "last")) {
    if (!v->is_boolean()) throw InputError(ParamPath("last"), "expected true or false");
    page.last = v->get<bool>();
  }
  const std::vector<Improvement> rows = store_.GetImprovements(job.id, page);
  Json list = Json::array();
  std::size_t bytes = 0;
  bool cut = false;
  for (const Improvement& improvement : rows) {
    if (!list.empty() && bytes > options_.limits.max_list_bytes) {
      cut = true;
      break;
    }
    bytes += improvement.genome.size() + 160;
    Json row;
    row["generation"] = improvement.generation;
    row["wall_seconds"] = improvement.wall_seconds;
    row["cost"] = improvement.cost;
    row["normalized_error"] = improvement.normalized_error;
    row["missing"] = proto::CountOrNull(improvement.missing);
    row["extra"] = proto::CountOrNull(improvement.extra);
    std::string genome(improvement.genome.size(), '0');
    for (std::size_t g = 0; g < genome.size(); ++g) {
      if (improvement.genome[g] != 0) genome[g] = '1';
    }
    row["genome"] = std::move(genome);
    list.push_back(std::move(row));
  }
  Json j;
  j["job_id"] = job.id;
  const bool more = !page.last && (cut || static_cast<int>(rows.size()) == page.limit);
  j["next_after"] = more ? Json(list.back()["generation"]) : Json(nullptr);
  j["improvements"] = std::move(list);
  return j;
}

Json RpcService::JobList(const Json& params) {
  proto::ExpectKeys(params, "params", {"state", "label", "limit", "cursor", "order"});
  JobFilter filter;
  if (const Json* v = OptionalParam(params, "order")) {
    const std::string order = proto::ReadString(*v, ParamPath("order"));
    if (order != "oldest" && order != "newest")
      throw InputError(ParamPath("order"),
                       "unknown order '" + order + "' (expected oldest or newest)");
    filter.newest_first = order == "newest";
  }
  if (const Json* v = OptionalParam(params, "state")) {
    const std::string name = proto::ReadString(*v, ParamPath("state"));
    filter.state = proto::ParseJobState(name);
    if (!filter.state) {
      throw InputError(
          ParamPath("state"),
          "unknown state '" + name +
              "' (expected preparing, queued, running, succeeded, failed or cancelled)");
    }
  }
  if (const Json* v = OptionalParam(params, "label"))
    filter.label = ReadBoundedString(*v, ParamPath("label"));
  filter.limit = ReadPageLimit(params, 100, options_.limits.max_page);
  if (const Json* v = OptionalParam(params, "cursor")) {
    const std::uint64_t cursor = proto::ReadUint64(*v, ParamPath("cursor"));
    if (cursor > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) {
      throw InputError(ParamPath("cursor"), "out of range");
    }
    filter.after_id = static_cast<std::int64_t>(cursor);
  }
  const JobPage page = store_.ListJobs(filter);
  Json j;
  Json jobs = Json::array();
  std::optional<std::int64_t> next_cursor = page.next_cursor;
  std::size_t bytes = 0;
  for (JobRecord job : page.jobs) {
    if (job.state == JobState::kRunning) {
      if (auto live = scheduler_.LiveProgress(job.id)) job.progress = live;
    }
    Json row = proto::JobToJson(job);
    bytes += row.dump().size();
    // A page ends early where it would grow past the byte bound; the cursor goes on from
    // the last job in it (at least one job per page, whatever its size).
    if (!jobs.empty() && bytes > options_.limits.max_list_bytes) {
      next_cursor = jobs.back().at("job_id").get<std::int64_t>();
      break;
    }
    jobs.push_back(std::move(row));
  }
  j["jobs"] = std::move(jobs);
  j["quarantined"] = QuarantinedToJson(page.quarantined, next_cursor, filter.newest_first);
  j["next_cursor"] = next_cursor ? Json(*next_cursor) : Json(nullptr);
  return j;
}

Json RpcService::JobCancel(const Json& params) {
  proto::ExpectKeys(params, "params", {"job_id"});
  const JobRecord job = RequireJob(params);
  const Scheduler::CancelOutcome outcome = scheduler_.Cancel(job.id);
  if (outcome == Scheduler::CancelOutcome::kNotActive) {
    Json data;
    data["state"] = proto::JobStateName(job.state);
    throw rpc::RpcError(rpc::kWrongState,
                        "job " + std::to_string(job.id) + " is " +
                            std::string(proto::JobStateName(job.state)) +
                            "; only a preparing, queued or running job can be cancelled",
                        data);
  }
  Json j;
  j["job_id"] = job.id;
  j["state"] = outcome == Scheduler::CancelOutcome::kCancelled ? "cancelled" : "cancelling";
  return j;
}

Json RpcService::JobDelete(const Json& params) {
  proto::ExpectKeys(params, "params", {"job_id"});
  const JobRecord job = RequireJob(params);
  // The store deletes finished jobs only; a job running here is past its end a moment longer
  // (announcing it), and deleting it then would hide its last notification.
  if (!proto::IsFinal(job.state) || scheduler_.IsRunningHere(job.id) || !store_.DeleteJob(job.id)) {
    Json data;
    data["state"] = proto::JobStateName(job.state);
    throw rpc::RpcError(rpc::kWrongState,
                        "job " + std::to_string(job.id) + " is " +
                            std::string(proto::JobStateName(job.state)) +
                            "; cancel it before deleting it",
                        data);
  }
  spdlog::info("job {} deleted", job.id);
  Json j;
  j["job_id"] = job.id;
  j["deleted"] = true;
  return j;
}

Json RpcService::JobWatch(const Json& params, SessionContext& session) {
  proto::ExpectKeys(params, "params", {"job_id"});
  const JobRecord before = RequireJob(params);
  // Each watch is fed by the daemon: one connection cannot ask for an unbounded stream. A
  // watch whose job has finished feeds nothing more: it is dropped and does not count.
  for (std::size_t w = session.watches.size(); w-- > 0;) {
    if (session.watch_finished[w]->load()) {
      scheduler_.Unwatch(session.watches[w]);
      session.watches.erase(session.watches.begin() + static_cast<std::ptrdiff_t>(w));
      session.watch_finished.erase(session.watch_finished.begin() + static_cast<std::ptrdiff_t>(w));
    }
  }
  if (static_cast<int>(session.watches.size()) >= options_.limits.max_watches) {
    LimitExceeded("max_watches", static_cast<std::int64_t>(session.watches.size()) + 1,
                  options_.limits.max_watches);
  }
  // job.finished at most once on this connection, whether the job's runner or this handler
  // (for a job already finished) sends it.
  auto finished_sent = std::make_shared<std::atomic<bool>>(false);
  auto notify = session.notify;
  std::optional<std::uint64_t> token;
  if (notify) {
    token = scheduler_.Watch(before.id, [notify, finished_sent](const Json& n) {
      const std::string method = n.value("method", "");
      if ((method == "job.finished" || method == "job.gone") && finished_sent->exchange(true))
        return;
      notify(n);
    });
  }
  // Read again after registering: a job that finished in between is not missed.
  JobRecord job;
  try {
    job = RequireJob(params);
  } catch (...) {
    if (token) scheduler_.Unwatch(*token);  // deleted in between: no job.finished will come
    throw;
  }
  if (token) {
    session.watches.push_back(*token);
    session.watch_finished.push_back(finished_sent);
  }
  if (proto::IsFinal(job.state) && notify && !finished_sent->exchange(true)) {
    notify(rpc::Notification("job.finished", proto::JobToJson(job)));
  }
  return proto::JobToJson(job);
}

}  // namespace springfit::server
