// Reading a method's params (server/rpc/): their paths in errors, optional members, bounded
// strings and page sizes, and the error of a server limit exceeded. Shared by the dispatcher,
// the submission and the job methods.
#pragma once
#include <cstdint>
#include <string>
#include <string_view>

#include "proto/json_reader.h"

namespace springfit::server {

// "params.<key>", for InputError paths.
std::string ParamPath(std::string_view key);
// The member, or null when it is absent or JSON null.
const proto::Json* OptionalParam(const proto::Json& params, const char* key);
// A string of at most kMaxLabelBytes bytes (labels, idempotency keys).
inline constexpr std::size_t kMaxLabelBytes = 200;
std::string ReadBoundedString(const proto::Json& v, const std::string& path);
// params.limit in [1, max], or `default_limit` when absent.
int ReadPageLimit(const proto::Json& params, int default_limit, int max);
// Throws the RPC error of a server limit (-32005) naming it, the value and the limit.
[[noreturn]] void LimitExceeded(const std::string& what, std::int64_t value, std::int64_t max);

}  // namespace springfit::server
