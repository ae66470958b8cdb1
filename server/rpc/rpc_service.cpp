#include "server/rpc/rpc_service.h"

#include "server/version.h"

#include <algorithm>
#include <chrono>
#include <limits>
#include <memory>
#include <thread>

#include <spdlog/spdlog.h>

#include "engine/candidates.h"
#include "engine/input_error.h"
#include "engine/interruption.h"
#include "engine/problem.h"
#include "engine/scene_validation.h"
#include "engine/search/search_options.h"
#include "proto/names.h"
#include "proto/rpc.h"
#include "proto/scene_codec.h"
#include "proto/search_codec.h"
#include "server/rpc/token.h"
#include "server/store/unix_time.h"

namespace springfit::server {
namespace rpc = proto::rpc;
using proto::Json;

namespace {

constexpr int kProtocolVersion = 1;
// server.info's count of the queue gives up after this (ScopedStoreDeadline): the answer comes
// within 2 s even when the database does not answer.
constexpr double kInfoStoreSeconds = 1.5;
constexpr std::size_t kMaxLabelBytes = 200;

std::string ParamPath(std::string_view key) {
  return proto::JoinPath("params", key);
}

const Json* Optional(const Json& params, const char* key) {
  const auto it = params.find(key);
  return it == params.end() || it->is_null() ? nullptr : &*it;
}

std::string ReadBoundedString(const Json& v, const std::string& path) {
  std::string s = proto::ReadString(v, path);
  if (s.size() > kMaxLabelBytes)
    throw InputError(path, "longer than " + std::to_string(kMaxLabelBytes) + " bytes");
  return s;
}

int ReadPageLimit(const Json& params, int default_limit, int max) {
  const Json* v = Optional(params, "limit");
  if (!v) return default_limit;
  const int limit = proto::ReadInt(*v, ParamPath("limit"));
  if (limit < 1 || limit > max) {
    throw InputError(ParamPath("limit"), "must be in [1, " + std::to_string(max) + "]");
  }
  return limit;
}

// job.preparing notifications to a submitter while its scene is prepared, this often.
constexpr int kPreparingNoticeSeconds = 5;
// How long a retry (the same idempotency key) waits for a first submission being prepared
// before it is answered busy.
constexpr int kRetryWaitSeconds = 60;

// job.preparing to a submitter whose job takes a while: after a second, then about every
// kPreparingNoticeSeconds (its answer timeout can count from the last one, however long the
// preparation). Most scenes are prepared before the first: their submitters see the answer
// alone.
class PreparingNotices {
 public:
  PreparingNotices(const SessionContext& session, std::int64_t id)
      : session_(session),
        id_(id),
        started_(std::chrono::steady_clock::now()),
        next_(started_ + std::chrono::seconds(1)) {}
  void Poll() {
    const auto now = std::chrono::steady_clock::now();
    if (!session_.notify_now || now < next_) return;
    next_ = now + std::chrono::seconds(kPreparingNoticeSeconds);
    Json params;
    params["job_id"] = id_;
    params["seconds"] = std::chrono::duration<double>(now - started_).count();
    session_.notify_now(rpc::Notification("job.preparing", params));
  }

 private:
  const SessionContext& session_;
  std::int64_t id_;
  std::chrono::steady_clock::time_point started_;
  std::chrono::steady_clock::time_point next_;
};

rpc::RpcError InvalidScene(const InputError& e) {
  Json data;
  data["path"] = e.path();
  return rpc::RpcError(rpc::kInvalidScene, std::string("invalid scene: ") + e.what(), data);
}

// A preparing job's lease lapsed (the store did not answer the heartbeats in time) and the
// job was swept: nothing of the submission remains.
rpc::RpcError RecordLost() {
  return rpc::RpcError(rpc::kStoreUnavailable,
                       "store unavailable: the submission's record was lost while its scene was "
                       "prepared (its lease could not be renewed); nothing was queued");
}

[[noreturn]] void LimitExceeded(const std::string& what, std::int64_t value, std::int64_t max) {
  Json data;
  data["limit"] = what;
  data["value"] = value;
  data["max"] = max;
  throw rpc::RpcError(
      rpc::kLimitExceeded,
      what + " " + std::to_string(value) + " exceeds this server's limit of " + std::to_string(max),
      data);
}

bool IsValidId(const Json& id) {
  return id.is_null() || id.is_string() || id.is_number();
}

}  // namespace

RpcService::RpcService(JobStore& store, Scheduler& scheduler, ServiceOptions options)
    : store_(store), scheduler_(scheduler), options_(std::move(options)) {}

RpcService::ParsedMessage RpcService::Parse(std::string_view text) {
  ParsedMessage parsed;
  try {
    parsed.message = proto::ParseJson(text);
  } catch (const InputError& e) {
    parsed.parse_error = rpc::Serialize(
        rpc::Error(nullptr, rpc::kParseError, std::string("parse error: ") + e.what()));
    return parsed;
  }
  // Ids that parsed as doubles are answered with the text they were sent as.
  parsed.ids.Protect(text, parsed.message);
  const auto submits = [](const Json& request) {
    if (!request.is_object()) return false;
    const auto method = request.find("method");
    return method != request.end() && method->is_string() &&
           method->get_ref<const std::string&>() == "job.submit";
  };
  parsed.prepares_scene = parsed.message.is_array()
                              ? std::any_of(parsed.message.begin(), parsed.message.end(), submits)
                              : submits(parsed.message);
  return parsed;
}

std::string RpcService::Handle(const ParsedMessage& parsed, SessionContext& session) {
  if (!parsed.parse_error.empty()) return parsed.parse_error;
  const Json response = HandleJson(parsed.message, session);
  return response.is_null() ? std::string() : parsed.ids.Restore(rpc::Serialize(response));
}

std::string RpcService::HandleMessage(std::string_view text, SessionContext& session) {
  return Handle(Parse(text), session);
}

Json RpcService::HandleJson(const Json& message, SessionContext& session) {
  if (!message.is_array()) return HandleRequest(message, session);
  if (message.empty())
    return rpc::Error(nullptr, rpc::kInvalidRequest, "invalid request: an empty batch");
  if (static_cast<int>(message.size()) > options_.limits.max_batch) {
    Json data;
    data["limit"] = "max_batch";
    data["value"] = message.size();
    data["max"] = options_.limits.max_batch;
    return rpc::Error(nullptr, rpc::kLimitExceeded,
                      "a batch of " + std::to_string(message.size()) +
                          " requests exceeds this server's limit of " +
                          std::to_string(options_.limits.max_batch),
                      data);
  }
  Json responses = Json::array();
  for (const Json& request : message) {
    Json response = HandleRequest(request, session);
    if (!response.is_null()) responses.push_back(std::move(response));
  }
  return responses.empty() ? Json(nullptr) : responses;
}

void RpcService::EndSession(SessionContext& session) {
  for (std::uint64_t token : session.watches) scheduler_.Unwatch(token);
  session.watches.clear();
  session.watch_finished.clear();
}

Json RpcService::HandleRequest(const Json& request, SessionContext& session) {
  if (!request.is_object())
    return rpc::Error(nullptr, rpc::kInvalidRequest, "invalid request: not an object");
  const auto id_it = request.find("id");
  const bool is_notification = id_it == request.end();
  const Json id = is_notification || !IsValidId(*id_it) ? Json(nullptr) : *id_it;
  auto invalid = [&](const std::string& why) {
    return rpc::Error(id, rpc::kInvalidRequest, "invalid request: " + why);
  };
  if (!is_notification && !IsValidId(*id_it))
    return invalid("id must be a string, a number or null");
  const auto version = request.find("jsonrpc");
  if (version == request.end() || *version != "2.0") return invalid("jsonrpc must be \"2.0\"");
  const auto method = request.find("method");
  if (method == request.end() || !method->is_string()) return invalid("method must be a string");
  for (const auto& [key, value] : request.items()) {
    if (key != "jsonrpc" && key != "id" && key != "method" && key != "params")
      return invalid("unknown member '" + key + "'");
  }
  Json params = Json::object();
  if (const auto p = request.find("params"); p != request.end()) {
    if (p->is_array()) {
      Json data;
      data["path"] = "params";
      return rpc::Error(id, rpc::kInvalidParams,
                        "invalid params: springfit methods take named params (an object)", data);
    }
    if (!p->is_object()) return invalid("params must be an object");
    params = *p;
  }
  Json response;
  try {
    response = rpc::Result(id, Dispatch(method->get<std::string>(), params, session));
  } catch (const rpc::RpcError& e) {
    response = rpc::Error(id, e.code(), e.what(), e.data());
  } catch (const InputError& e) {
    Json data;
    data["path"] = e.path();
    response =
        rpc::Error(id, rpc::kInvalidParams, std::string("invalid params: ") + e.what(), data);
  } catch (const StoreCorrupt& e) {
    // Not the client's fault, and not to be retried: the database holds a damaged record.
    const std::uint64_t incident = ++incidents_;
    spdlog::error("{}: damaged record in the store (incident {}): {}", method->get<std::string>(),
                  incident, e.what());
    Json data;
    data["incident"] = incident;
    response = rpc::Error(id, rpc::kStoreCorrupt,
                          std::string("the store holds a damaged record (incident ") +
                              std::to_string(incident) + " in the server's log): " + e.what(),
                          data);
  } catch (const StoreUnavailable& e) {
    // Nothing was stored or changed: the client may retry (with its idempotency key).
    response = rpc::Error(id, rpc::kStoreUnavailable,
                          std::string("store unavailable, try again: ") + e.what());
  } catch (const std::bad_alloc&) {
    spdlog::error("{}: out of memory", method->get<std::string>());
    response = rpc::Error(id, rpc::kInternalError,
                          "internal error: out of memory: the server could not get the memory "
                          "this request needs");
  } catch (const std::exception& e) {
    // The exception's own text (a library's, quoting internals) goes to the log; the client
    // gets the documented message and the incident's number to find it there.
    const std::uint64_t incident = ++incidents_;
    spdlog::error("{}: internal error (incident {}): {}", method->get<std::string>(), incident,
                  e.what());
    Json data;
    data["incident"] = incident;
    response = rpc::Error(id, rpc::kInternalError,
                          "internal error: the request failed inside the server (incident " +
                              std::to_string(incident) + " in its log)",
                          data);
  }
  if (options_.metrics) {
    // Unknown methods under one name: a client cannot grow the metrics without bound.
    const bool unknown =
        response.contains("error") && response["error"].value("code", 0) == rpc::kMethodNotFound;
    options_.metrics->CountRequest(unknown ? "unknown" : method->get<std::string>(),
                                   response.contains("error"));
  }
  return is_notification ? Json(nullptr) : response;
}

Json RpcService::Dispatch(const std::string& method, const Json& params, SessionContext& session) {
  if (method == "server.info") {
    proto::ExpectKeys(params, "params", {});
    return ServerInfo();
  }
  if (method == "session.auth") return SessionAuth(params, session);
  using Handler = Json (RpcService::*)(const Json&);
  static const std::pair<const char*, Handler> kJobMethods[] = {
      {"job.get", &RpcService::JobGet},       {"job.result", &RpcService::JobResult},
      {"job.trace", &RpcService::JobTrace},   {"job.list", &RpcService::JobList},
      {"job.cancel", &RpcService::JobCancel}, {"job.delete", &RpcService::JobDelete},
      {"job.scene", &RpcService::JobScene},   {"job.improvements", &RpcService::JobImprovements},
  };
  const bool known = method == "job.watch" || method == "job.submit" ||
                     std::any_of(std::begin(kJobMethods), std::end(kJobMethods),
                                 [&](const auto& m) { return method == m.first; });
  if (!known) throw rpc::RpcError(rpc::kMethodNotFound, "method not found: " + method);
  if (!options_.token.empty() && !session.authenticated) {
    throw rpc::RpcError(rpc::kUnauthorized,
                        "unauthorized: call session.auth with the server's token first");
  }
  if (method == "job.watch") return JobWatch(params, session);
  if (method == "job.submit") return JobSubmit(params, session);
  for (const auto& [name, handler] : kJobMethods) {
    if (method == name) return (this->*handler)(params);
  }
  throw rpc::RpcError(rpc::kMethodNotFound, "method not found: " + method);
}

Json RpcService::ServerInfo() {
  Json j;
  j["name"] = "springfitd";
  j["version"] = kVersion;
  j["protocol"] = kProtocolVersion;
  j["auth_required"] = !options_.token.empty();
  j["workers"] = options_.workers;
  j["max_running"] = options_.max_running;
  j["daemon"] = scheduler_.owner();
  j["store"] = store_.Describe();
  j["running"] = scheduler_.running();
  // All daemons' queue; null with the reason when the store does not answer, so that
  // server.info still tells the daemon is up.
  try {
    // server.info answers within 2 s whatever the store does: it tells the daemon is up.
    const ScopedStoreDeadline quick(kInfoStoreSeconds);
    j["queued"] = store_.CountQueued();
  } catch (const std::exception& e) {
    j["queued"] = nullptr;
    j["store_error"] = e.what();
  }
  Json strategies = Json::array();
  for (Strategy s : proto::AllStrategies()) strategies.push_back(proto::StrategyName(s));
  j["strategies"] = std::move(strategies);
  Json limits;
  limits["max_nodes"] = options_.limits.max_nodes;
  limits["max_genes"] = options_.limits.max_genes;
  limits["max_candidates"] = options_.limits.max_candidates;
  limits["max_population"] = options_.limits.max_population;
  limits["max_population_genes"] = options_.limits.max_population_genes;
  limits["max_generations"] = options_.limits.max_generations;
  limits["max_queued"] = options_.limits.max_queued;
  limits["max_batch"] = options_.limits.max_batch;
  limits["max_page"] = options_.limits.max_page;
  j["limits"] = limits;
  return j;
}

Json RpcService::SessionAuth(const Json& params, SessionContext& session) {
  proto::ExpectKeys(params, "params", {"token"});
  const std::string token =
      proto::ReadString(proto::RequiredMember(params, "params", "token"), ParamPath("token"));
  if (options_.token.empty()) {
    session.authenticated = true;
  } else if (SameToken(options_.token, token)) {
    session.authenticated = true;
  } else {
    session.authenticated = false;
    if (++session.wrong_tokens == 1)
      spdlog::warn("session.auth: wrong token (not logged again for this connection)");
    if (session.wrong_tokens >= kMaxWrongTokens) {
      session.close = true;
      spdlog::warn("session.auth: {} wrong tokens on one connection: closed", kMaxWrongTokens);
      throw rpc::RpcError(rpc::kUnauthorized, "unauthorized: wrong token (" +
                                                  std::to_string(kMaxWrongTokens) +
                                                  " wrong tokens: the connection is closed)");
    }
    throw rpc::RpcError(rpc::kUnauthorized, "unauthorized: wrong token");
  }
  Json j;
  j["authenticated"] = true;
  return j;
}

Json RpcService::JobSubmit(const Json& params, SessionContext& session) {
  proto::ExpectKeys(params, "params", {"scene", "label", "priority", "seed", "idempotency_key"});
  if (stopping()) throw rpc::RpcError(rpc::kBusy, "busy: the server is shutting down");
  NewJob job;
  JobRecord& r = job.record;
  if (const Json* v = Optional(params, "label"))
    r.label = ReadBoundedString(*v, ParamPath("label"));
  if (const Json* v = Optional(params, "priority")) {
    r.priority = proto::ReadInt(*v, ParamPath("priority"));
    if (r.priority < -1000 || r.priority > 1000)
      throw InputError(ParamPath("priority"), "must be in [-1000, 1000]");
  }
  if (const Json* v = Optional(params, "idempotency_key")) {
    r.idempotency_key = ReadBoundedString(*v, ParamPath("idempotency_key"));
    if (r.idempotency_key.empty())
      throw InputError(ParamPath("idempotency_key"), "must not be empty");
  }
  std::optional<std::uint64_t> seed;
  if (const Json* v = Optional(params, "seed")) seed = proto::ReadUint64(*v, ParamPath("seed"));
  const Json& scene_json = proto::RequiredMember(params, "params", "scene");
  if (!scene_json.is_object())
    throw InputError(ParamPath("scene"), "expected a scene object (proto/SCENE.md)");
  // The name is shown in every listing and log line: bounded before anything is built.
  if (const auto name = scene_json.find("name");
      name != scene_json.end() && name->is_string() &&
      name->get_ref<const std::string&>().size() > kMaxLabelBytes) {
    Json data;
    data["path"] = "scene.name";
    throw rpc::RpcError(
        rpc::kInvalidScene,
        "invalid scene: scene.name: longer than " + std::to_string(kMaxLabelBytes) + " bytes",
        data);
  }

  // At the door, in time linear in the scene's size: its structure (ValidateScene) and every
  // bound known before it is prepared. A scene refused here leaves no job.
  Scene scene;
  try {
    scene = proto::SceneFromJson(scene_json);
    if (scene.node_count() > options_.limits.max_nodes) {
      LimitExceeded("max_nodes", scene.node_count(), options_.limits.max_nodes);
    }
    if (scene.search.max_generations > options_.limits.max_generations) {
      LimitExceeded("max_generations", scene.search.max_generations,
                    options_.limits.max_generations);
    }
    if (scene.search.population && *scene.search.population > options_.limits.max_population) {
      LimitExceeded("max_population", *scene.search.population, options_.limits.max_population);
    }
    // Before any candidate is generated: a spec asking for billions of pairs is refused here.
    const std::int64_t candidates = EstimateCandidateCount(scene, options_.limits.max_candidates);
    if (candidates > options_.limits.max_candidates) {
      LimitExceeded("max_candidates", candidates, options_.limits.max_candidates);
    }
    ValidateScene(scene);
  } catch (const InputError& e) {
    throw InvalidScene(e);
  }
  if (seed) scene.search.seed = *seed;
  r.seed = scene.search.seed;
  r.scene_name = scene.name;
  r.strategy = proto::StrategyName(scene.search.strategy);
  r.max_generations = scene.search.max_generations;
  r.created_at = UnixNow();
  job.scene_json = proto::SceneToJson(scene).dump();
  // The job exists from here, `preparing`: listed, and cancellable through any daemon, while
  // its reference is solved (seconds to minutes for a large scene).
  job.preparing_owner = scheduler_.owner();
  job.lease_seconds = scheduler_.lease_seconds();
  JobStore::Created created = store_.CreateJob(job, options_.limits.max_queued);
  // A retry of a submission still being prepared waits for its outcome (the first may yet
  // be refused, and its job then vanishes: the retry then submits anew).
  for (int round = 0; !created.created && !created.queue_full &&
                      created.job.state == JobState::kPreparing && round < 2;
       ++round) {
    std::optional<JobRecord> now = WaitWhilePreparing(created.job.id, session);
    if (now) {
      created.job = *now;
    } else {
      created = store_.CreateJob(job, options_.limits.max_queued);
    }
  }
  if (created.queue_full) {
    throw rpc::RpcError(rpc::kBusy, "busy: " + std::to_string(options_.limits.max_queued) +
                                        " jobs are queued already");
  }
  if (!created.created) {
    // The key names one submission: a retry must ask for the same computation (the scene with
    // its search settings, and the seed), or a pipeline that changed its scene would silently
    // get the old job's result. Label and priority stay the first submission's.
    const JobRecord& old = created.job;
    std::string differs;
    if (old.seed != r.seed) differs = "seed";
    const std::optional<std::string> old_scene = store_.GetScene(old.id);
    if (old_scene && *old_scene != job.scene_json)
      differs += std::string(differs.empty() ? "" : ", ") + "scene";
    if (!differs.empty()) {
      Json data;
      data["path"] = "params.idempotency_key";
      data["job_id"] = old.id;
      throw rpc::RpcError(rpc::kInvalidParams,
                          "params.idempotency_key: already used by job " + std::to_string(old.id) +
                              " with a different " + differs +
                              " (a key names one submission; use a new key for a new one)",
                          data);
    }
    if (old.state == JobState::kPreparing) {
      Json data;
      data["job_id"] = old.id;
      throw rpc::RpcError(rpc::kBusy,
                          "busy: job " + std::to_string(old.id) +
                              " of this idempotency key is still being prepared (its first "
                              "submission is not answered yet); retry",
                          data);
    }
    Json j;
    j["created"] = false;
    j["job"] = proto::JobToJson(created.job);
    return j;
  }
  const JobRecord prepared = Prepare(created, std::move(scene), session);
  Json j;
  j["created"] = true;
  j["job"] = proto::JobToJson(prepared);
  return j;
}

std::optional<JobRecord> RpcService::WaitWhilePreparing(std::int64_t id,
                                                        const SessionContext& session) {
  PreparingNotices notices(session, id);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(kRetryWaitSeconds);
  while (std::chrono::steady_clock::now() < deadline) {
    if (stopping()) throw rpc::RpcError(rpc::kBusy, "busy: the server is shutting down");
    if (session.peer_gone && session.peer_gone->load())
      throw rpc::RpcError(rpc::kBusy, "busy: the connection closed");
    std::optional<JobRecord> job = store_.GetJob(id);
    if (!job || job->state != JobState::kPreparing) return job;
    notices.Poll();
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return store_.GetJob(id);
}

JobRecord RpcService::Prepare(const JobStore::Created& created, Scene scene,
                              const SessionContext& session) {
  const Lease& lease = created.lease;
  const std::int64_t id = lease.job_id;
  JobRecord r = created.job;
  const auto control = scheduler_.PreparationStarted(lease);
  // Whatever ends the preparation, the job leaves it: queued or cancelled, or else dropped
  // (never acknowledged: the submitter gets an error, or has gone).
  std::optional<JobRecord> outcome;
  struct Ending {
    RpcService& service;
    const Lease& lease;
    std::optional<JobRecord>& outcome;
    ~Ending() {
      bool dropped = false;
      if (!outcome) {
        try {
          service.store_.DropPreparing(lease);
          dropped = true;
        } catch (const std::exception& e) {
          // The next claim deletes it once its lease, no longer renewed, expires (and the
          // monitor then tells its watchers).
          spdlog::warn("job {}: cannot drop the refused submission now ({})", lease.job_id,
                       e.what());
        }
      }
      try {
        service.scheduler_.PreparationEnded(lease.job_id, outcome, dropped);
      } catch (const std::exception& e) {  // (out of memory telling the watchers)
        spdlog::error("job {}: {}", lease.job_id, e.what());
      }
    }
  } ending{*this, lease, outcome};

  PreparingNotices notices(session, id);
  const std::shared_ptr<const std::atomic<bool>> peer_gone = session.peer_gone;
  const auto stop_requested = [&] {
    return control->cancel.load() || control->lease_lost.load() || stopping() ||
           (peer_gone && peer_gone->load());
  };
  Interruption interruption(
      [&] {
        notices.Poll();
        return stop_requested();
      },
      0.1);
  // The preparation stopped, or a stop came after its last check (then too, the job is not
  // queued for a submitter that has gone or a server that stops).
  const auto stopped = [&]() -> JobRecord {
    if (control->cancel.load() && !control->lease_lost.load()) {
      r.state = JobState::kCancelled;
      r.finished_at = UnixNow();
      try {
        store_.MarkFinished(lease, {r.state, "", "", std::nullopt, r.finished_at, ""});
      } catch (const LeaseLost&) {
        throw RecordLost();
      }
      spdlog::info("job {} cancelled while being prepared ({})", id, r.scene_name);
      outcome = r;
      return r;
    }
    if (control->lease_lost.load()) throw RecordLost();
    if (stopping()) throw rpc::RpcError(rpc::kBusy, "busy: the server is shutting down");
    spdlog::info("job {}: its submitter went away while it was prepared; dropped", id);
    throw rpc::RpcError(rpc::kBusy, "busy: the connection closed");
  };
  std::shared_ptr<const Problem> problem;
  try {
    problem =
        std::make_shared<const Problem>(std::move(scene), EquilibriumOptions{}, &interruption);
  } catch (const InputError& e) {
    throw InvalidScene(e);
  } catch (const Interrupted&) {
    return stopped();
  }
  if (stop_requested()) return stopped();
  if (problem->gene_count() > options_.limits.max_genes) {
    LimitExceeded("max_genes", problem->gene_count(), options_.limits.max_genes);
  }
  const SearchOptions options =
      ResolveSearchOptions(problem->scene().search, problem->gene_count());
  // Before the job is queued: the search would hold population x genes bytes per generation.
  const std::int64_t population_genes =
      static_cast<std::int64_t>(options.population) * problem->gene_count();
  if (population_genes > options_.limits.max_population_genes) {
    LimitExceeded("max_population_genes", population_genes, options_.limits.max_population_genes);
  }
  r.genes = problem->gene_count();
  r.max_generations = options.max_generations;
  // The strategy that runs, `default` resolved (the stored scene keeps what was asked).
  r.strategy = proto::StrategyName(ResolvedStrategy(options.strategy, problem->scene()));
  try {
    r.state = store_.FinishPreparing(lease, r);
  } catch (const LeaseLost&) {
    throw RecordLost();
  }
  if (r.state == JobState::kCancelled) r.finished_at = UnixNow();
  outcome = r;
  if (r.state == JobState::kCancelled) {
    // (A cancel reached the store after the last heartbeat: it wins.)
    spdlog::info("job {} cancelled while being prepared ({})", id, r.scene_name);
    return r;
  }
  spdlog::info("job {} queued ({}, label '{}', priority {}, seed {})", id, r.scene_name, r.label,
               r.priority, r.seed);
  scheduler_.JobSubmitted(id, std::move(problem));
  return r;
}

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
  if (const Json* v = Optional(params, "after")) after = proto::ReadInt(*v, ParamPath("after"));
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
  if (const Json* v = Optional(params, "after"))
    page.after = proto::ReadInt(*v, ParamPath("after"));
  page.limit = ReadPageLimit(params, 1000, options_.limits.max_page);
  if (const Json* v = Optional(params, "last")) {
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
  if (const Json* v = Optional(params, "order")) {
    const std::string order = proto::ReadString(*v, ParamPath("order"));
    if (order != "oldest" && order != "newest")
      throw InputError(ParamPath("order"),
                       "unknown order '" + order + "' (expected oldest or newest)");
    filter.newest_first = order == "newest";
  }
  if (const Json* v = Optional(params, "state")) {
    const std::string name = proto::ReadString(*v, ParamPath("state"));
    filter.state = proto::ParseJobState(name);
    if (!filter.state) {
      throw InputError(
          ParamPath("state"),
          "unknown state '" + name +
              "' (expected preparing, queued, running, succeeded, failed or cancelled)");
    }
  }
  if (const Json* v = Optional(params, "label"))
    filter.label = ReadBoundedString(*v, ParamPath("label"));
  filter.limit = ReadPageLimit(params, 100, options_.limits.max_page);
  if (const Json* v = Optional(params, "cursor")) {
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
