#include "proto/rpc.h"

namespace springfit::proto::rpc {

Json Request(std::int64_t id, const std::string& method, Json params) {
  Json j;
  j["jsonrpc"] = "2.0";
  j["id"] = id;
  j["method"] = method;
  j["params"] = std::move(params);
  return j;
}

Json Notification(const std::string& method, Json params) {
  Json j;
  j["jsonrpc"] = "2.0";
  j["method"] = method;
  j["params"] = std::move(params);
  return j;
}

Json Result(const Json& id, Json result) {
  Json j;
  j["jsonrpc"] = "2.0";
  j["id"] = id;
  j["result"] = std::move(result);
  return j;
}

Json Error(const Json& id, int code, const std::string& message, const Json& data) {
  Json error;
  error["code"] = code;
  error["message"] = message;
  if (!data.is_null()) error["data"] = data;
  Json j;
  j["jsonrpc"] = "2.0";
  j["id"] = id;
  j["error"] = std::move(error);
  return j;
}

std::string Serialize(const Json& message) {
  return message.dump(-1, ' ', false, Json::error_handler_t::replace) + "\n";
}

}  // namespace springfit::proto::rpc
