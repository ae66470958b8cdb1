#include "proto/rpc.h"

#include <algorithm>

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

namespace {

// Placeholder of the k-th literal: "\x01springfit-id-literal-k\x01" (see IdLiterals).
std::string Placeholder(std::size_t k) {
  return "\x01springfit-id-literal-" + std::to_string(k) + "\x01";
}

// A SAX pass that finds, for each request of a message (the top-level object, or each
// element of a top-level array), the literal text of an `id` that parses as a double.
class FloatIdFinder {
 public:
  using string_t = Json::string_t;
  std::vector<std::pair<std::size_t, std::string>> found;  // (request index, literal)

  bool null() { return Value(); }
  bool boolean(bool) { return Value(); }
  bool number_integer(Json::number_integer_t) { return Value(); }
  bool number_unsigned(Json::number_unsigned_t) { return Value(); }
  bool number_float(Json::number_float_t, const string_t& literal) {
    if (expecting_id_ && depth_ == RequestDepth()) found.emplace_back(Request(), literal);
    return Value();
  }
  bool string(string_t&) { return Value(); }
  bool binary(Json::binary_t&) { return Value(); }
  bool start_object(std::size_t) { return Open(true); }
  bool end_object() { return Close(); }
  bool start_array(std::size_t) { return Open(false); }
  bool end_array() { return Close(); }
  bool key(string_t& k) {
    expecting_id_ = depth_ == RequestDepth() && k == "id";
    return true;
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) {
    return false;
  }

 private:
  // Requests are objects at depth 1 (a single request) or 2 (in a batch).
  int RequestDepth() const { return batch_ ? 2 : 1; }
  std::size_t Request() const { return batch_ ? element_ : 0; }
  bool Value() {
    expecting_id_ = false;
    if (batch_ && depth_ == 1) ++element_;
    return true;
  }
  bool Open(bool object) {
    if (depth_ == 0) batch_ = !object;
    expecting_id_ = false;
    ++depth_;
    return true;
  }
  bool Close() {
    --depth_;
    if (batch_ && depth_ == 1) ++element_;
    return true;
  }

  int depth_ = 0;
  bool batch_ = false;
  std::size_t element_ = 0;  // the batch element being read
  bool expecting_id_ = false;
};

bool HasDoubleId(const Json& request) {
  if (!request.is_object()) return false;
  // On the object itself: GCC 12 sees a possible null inside json's own iterator here.
  const Json::object_t& object = request.get_ref<const Json::object_t&>();
  const auto id = object.find("id");
  return id != object.end() && id->second.is_number_float();
}

}  // namespace

void IdLiterals::Protect(std::string_view text, Json& message) {
  const bool any = message.is_array() ? std::any_of(message.begin(), message.end(), HasDoubleId)
                                      : HasDoubleId(message);
  if (!any) return;  // the common case: no second pass
  FloatIdFinder finder;
  Json::sax_parse(text, &finder);
  for (const auto& [index, literal] : finder.found) {
    Json& request = message.is_array() ? message[index] : message;
    if (!HasDoubleId(request)) continue;
    request["id"] = Placeholder(literals_.size());
    literals_.push_back(literal);
  }
}

std::string IdLiterals::Restore(std::string serialized) const {
  for (std::size_t k = 0; k < literals_.size(); ++k) {
    // As Serialize writes the placeholder: a JSON string, its control characters escaped.
    const std::string quoted = Json(Placeholder(k)).dump();
    for (std::size_t at = serialized.find(quoted); at != std::string::npos;
         at = serialized.find(quoted, at + literals_[k].size()))
      serialized.replace(at, quoted.size(), literals_[k]);
  }
  return serialized;
}

}  // namespace springfit::proto::rpc
