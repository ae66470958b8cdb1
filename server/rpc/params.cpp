#include "server/rpc/params.h"

#include "engine/api/input_error.h"
#include "proto/rpc.h"

namespace springfit::server {
namespace rpc = proto::rpc;
using proto::Json;

std::string ParamPath(std::string_view key) {
  return proto::JoinPath("params", key);
}

const Json* OptionalParam(const Json& params, const char* key) {
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
  const Json* v = OptionalParam(params, "limit");
  if (!v) return default_limit;
  const int limit = proto::ReadInt(*v, ParamPath("limit"));
  if (limit < 1 || limit > max) {
    throw InputError(ParamPath("limit"), "must be in [1, " + std::to_string(max) + "]");
  }
  return limit;
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

}  // namespace springfit::server
