// JSON-RPC 2.0 as springfit speaks it (proto/RPC.md): error codes, and the request, response
// and notification objects both the daemon and the client build.
#pragma once
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "proto/json_reader.h"

namespace springfit::proto::rpc {

// The standard's codes, then springfit's application codes (-32000..-32099).
inline constexpr int kParseError = -32700;
inline constexpr int kInvalidRequest = -32600;
inline constexpr int kMethodNotFound = -32601;
inline constexpr int kInvalidParams = -32602;
inline constexpr int kInternalError = -32603;
inline constexpr int kUnauthorized = -32001;  // session.auth first (or a wrong token)
inline constexpr int kNoSuchJob = -32002;
inline constexpr int kInvalidScene = -32003;      // data.path: the bad field inside the scene
inline constexpr int kLimitExceeded = -32004;     // data.limit: which bound (message, nodes, ...)
inline constexpr int kBusy = -32005;              // queue full, connection limit, shutting down
inline constexpr int kWrongState = -32006;        // e.g. deleting a running job
inline constexpr int kStoreUnavailable = -32007;  // the database does not answer; retry later
inline constexpr int kStoreCorrupt = -32008;      // a stored record is damaged; data.incident

// An error a method reports; `data` is attached to the error object when not null.
class RpcError : public std::runtime_error {
 public:
  RpcError(int code, const std::string& message, Json data = nullptr)
      : std::runtime_error(message), code_(code), data_(std::move(data)) {}
  int code() const { return code_; }
  const Json& data() const { return data_; }

 private:
  int code_;
  Json data_;
};

Json Request(std::int64_t id, const std::string& method, Json params);
Json Notification(const std::string& method, Json params);
Json Result(const Json& id, Json result);
Json Error(const Json& id, int code, const std::string& message, const Json& data = nullptr);

// The one-line form every message is written in: compact JSON and a newline. Invalid UTF-8
// in strings (which only an echo of client input could carry) is replaced, never thrown on.
std::string Serialize(const Json& message);

}  // namespace springfit::proto::rpc

namespace springfit::proto::rpc {

// A request id is echoed back exactly as it was sent (JSON-RPC 2.0). Integers survive parsing;
// a number parsed as a double may not (18446744073709551616, 1.50). So before a message is
// handled, each request's (top-level or batch element) id that parsed as a double is replaced
// by a placeholder string and its literal text kept here; RestoreIds() puts the literals back
// into the serialized answer. The placeholder holds a control character, which no id string
// that a client sends can equal once serialized (it is written as \u0001).
class IdLiterals {
 public:
  // `message` was parsed from `text`. Replaces its double ids by placeholders.
  void Protect(std::string_view text, Json& message);
  // The serialized answer with each placeholder replaced by its literal.
  std::string Restore(std::string serialized) const;

 private:
  std::vector<std::string> literals_;
};

}  // namespace springfit::proto::rpc
