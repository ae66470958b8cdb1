// The JSON-RPC service (server/rpc/rpc_service.h): parsing, the dispatcher, authentication and
// server.info; job.submit is in job_submission.cpp, the other job methods in job_methods.cpp.
#include "server/rpc/rpc_service.h"

#include "server/version.h"

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

constexpr int kProtocolVersion = 1;
// server.info's count of the queue gives up after this (ScopedStoreDeadline): the answer comes
// within 2 s even when the database does not answer.
constexpr double kInfoStoreSeconds = 1.5;

bool IsValidId(const Json& id) {
  return id.is_null() || id.is_string() || id.is_number();
}

// The request's JSON-RPC 2.0 envelope checked: the error response to send, or nullopt when it is
// well formed (then `method` is a string and `params`, if present, an object).
std::optional<Json> EnvelopeError(const Json& request, const Json& id, bool is_notification) {
  auto invalid = [&](const std::string& why) {
    return rpc::Error(id, rpc::kInvalidRequest, "invalid request: " + why);
  };
  if (!is_notification && !IsValidId(request["id"]))
    return invalid("id must be a string, a number or null");
  const auto version = request.find("jsonrpc");
  if (version == request.end() || *version != "2.0") return invalid("jsonrpc must be \"2.0\"");
  const auto method = request.find("method");
  if (method == request.end() || !method->is_string()) return invalid("method must be a string");
  for (const auto& [key, value] : request.items()) {
    if (key != "jsonrpc" && key != "id" && key != "method" && key != "params")
      return invalid("unknown member '" + key + "'");
  }
  if (const auto p = request.find("params"); p != request.end()) {
    if (p->is_array()) {
      Json data;
      data["path"] = "params";
      return rpc::Error(id, rpc::kInvalidParams,
                        "invalid params: springfit methods take named params (an object)", data);
    }
    if (!p->is_object()) return invalid("params must be an object");
  }
  return std::nullopt;
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
  if (std::optional<Json> error = EnvelopeError(request, id, is_notification)) return *error;
  const std::string method = request["method"].get<std::string>();
  const Json params = request.value("params", Json::object());
  Json response;
  try {
    response = rpc::Result(id, Dispatch(method, params, session));
  } catch (...) {
    response = ErrorOfCurrentException(id, method);
  }
  if (options_.metrics) {
    // Unknown methods under one name: a client cannot grow the metrics without bound.
    const bool unknown =
        response.contains("error") && response["error"].value("code", 0) == rpc::kMethodNotFound;
    options_.metrics->CountRequest(unknown ? "unknown" : method, response.contains("error"));
  }
  return is_notification ? Json(nullptr) : response;
}

Json RpcService::ErrorOfCurrentException(const Json& id, const std::string& method) {
  try {
    throw;
  } catch (const rpc::RpcError& e) {
    return rpc::Error(id, e.code(), e.what(), e.data());
  } catch (const InputError& e) {
    Json data;
    data["path"] = e.path();
    return rpc::Error(id, rpc::kInvalidParams, std::string("invalid params: ") + e.what(), data);
  } catch (const StoreCorrupt& e) {
    // Not the client's fault, and not to be retried: the database holds a damaged record. A
    // quarantined job's was logged, once, under its own incident by the store.
    if (e.incident() > 0) {
      Json data;
      data["incident"] = e.incident();
      data["quarantined"] = true;
      return rpc::Error(id, rpc::kStoreCorrupt,
                        std::string("the store holds a damaged record: ") + e.what(), data);
    }
    const std::uint64_t incident = ++incidents_;
    spdlog::error("{}: damaged record in the store (incident {}): {}", method, incident, e.what());
    Json data;
    data["incident"] = incident;
    return rpc::Error(id, rpc::kStoreCorrupt,
                      std::string("the store holds a damaged record (incident ") +
                          std::to_string(incident) + " in the server's log): " + e.what(),
                      data);
  } catch (const StoreUnavailable& e) {
    // Nothing was stored or changed: the client may retry (with its idempotency key).
    return rpc::Error(id, rpc::kStoreUnavailable,
                      std::string("store unavailable, try again: ") + e.what());
  } catch (const std::bad_alloc&) {
    spdlog::error("{}: out of memory", method);
    return rpc::Error(id, rpc::kInternalError,
                      "internal error: out of memory: the server could not get the memory "
                      "this request needs");
  } catch (const std::exception& e) {
    // The exception's own text (a library's, quoting internals) goes to the log; the client
    // gets the documented message and the incident's number to find it there.
    const std::uint64_t incident = ++incidents_;
    spdlog::error("{}: internal error (incident {}): {}", method, incident, e.what());
    Json data;
    data["incident"] = incident;
    return rpc::Error(id, rpc::kInternalError,
                      "internal error: the request failed inside the server (incident " +
                          std::to_string(incident) + " in its log)",
                      data);
  }
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

}  // namespace springfit::server
