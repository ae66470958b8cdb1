#include "proto/json_reader.h"

#include <cmath>
#include <limits>

#include "engine/api/input_error.h"

namespace springfit::proto {
namespace {

std::string TypeName(const Json& v) {
  switch (v.type()) {
    case Json::value_t::null:
      return "null";
    case Json::value_t::object:
      return "an object";
    case Json::value_t::array:
      return "an array";
    case Json::value_t::string:
      return "a string";
    case Json::value_t::boolean:
      return "a boolean";
    case Json::value_t::number_integer:
    case Json::value_t::number_unsigned:
      return "an integer";
    case Json::value_t::number_float:
      return "a number";
    default:
      return "an unsupported value";
  }
}

[[noreturn]] void WrongType(const Json& v, const std::string& path, const char* expected) {
  throw InputError(path, std::string("expected ") + expected + ", got " + TypeName(v));
}

}  // namespace

std::string JoinPath(const std::string& path, std::string_view key) {
  return path.empty() ? std::string(key) : path + "." + std::string(key);
}

std::string IndexPath(const std::string& path, std::size_t index) {
  return path + "[" + std::to_string(index) + "]";
}

const Json& RequiredMember(const Json& value, const std::string& path, std::string_view key) {
  const auto it = value.find(std::string(key));
  if (it == value.end()) throw InputError(JoinPath(path, key), "required");
  return *it;
}

Json ParseJson(std::string_view text) {
  try {
    return Json::parse(text.begin(), text.end());
  } catch (const Json::parse_error& e) {
    // Turn the byte offset into a line and column a person can find.
    std::size_t line = 1, column = 1;
    for (std::size_t i = 0; i + 1 < e.byte && i < text.size(); ++i) {
      if (text[i] == '\n') {
        ++line;
        column = 1;
      } else {
        ++column;
      }
    }
    // nlohmann's message repeats the position: keep what follows it.
    std::string what = e.what();
    const std::size_t column_at = what.find("column ");
    const std::size_t colon = what.find(": ", column_at == std::string::npos ? 0 : column_at);
    if (colon != std::string::npos) what = what.substr(colon + 2);
    throw InputError("", "invalid JSON at line " + std::to_string(line) + ", column " +
                             std::to_string(column) + ": " + what);
  } catch (const Json::exception& e) {
    // e.g. a number beyond the double range: out_of_range rather than a parse error.
    throw InputError("", std::string("invalid JSON: ") + e.what());
  }
}

void ExpectKeys(const Json& value, const std::string& path,
                std::initializer_list<std::string_view> allowed) {
  if (!value.is_object())
    WrongType(value, path.empty() ? std::string("(top level)") : path, "an object");
  for (const auto& [key, _] : value.items()) {
    bool known = false;
    for (std::string_view a : allowed) known = known || key == a;
    if (!known) {
      std::string list;
      for (std::string_view a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
      throw InputError(JoinPath(path, key), "unknown field (expected one of: " + list + ")");
    }
  }
}

void ExpectArray(const Json& value, const std::string& path) {
  if (!value.is_array()) WrongType(value, path, "an array");
}

void ExpectObject(const Json& value, const std::string& path) {
  if (!value.is_object()) WrongType(value, path, "an object");
}

double ReadNumber(const Json& value, const std::string& path) {
  if (!value.is_number()) WrongType(value, path, "a number");
  const double x = value.get<double>();
  if (!std::isfinite(x)) throw InputError(path, "not a finite number");
  return x;
}

std::vector<long long> ReadTags(const Json& value, const std::string& path, std::size_t count,
                                std::string_view what) {
  ExpectArray(value, path);
  if (value.size() != count) {
    throw InputError(path, std::to_string(value.size()) + " tags for " + std::to_string(count) +
                               " " + std::string(what) + " (one tag each, in their order)");
  }
  return ReadArray<long long>(value, path, [](const Json& tag, const std::string& p) {
    const double t = ReadNumber(tag, p);
    // (Within a double's exact integers: a tag is a number a mesh file wrote.)
    if (t != std::floor(t) || std::abs(t) > 9007199254740992.0)
      throw InputError(p, "must be an integer");
    return static_cast<long long>(t);
  });
}

int ReadInt(const Json& value, const std::string& path) {
  if (value.is_number_integer()) {
    if (value.is_number_unsigned()) {
      const auto u = value.get<std::uint64_t>();
      if (u > static_cast<std::uint64_t>(std::numeric_limits<int>::max())) {
        throw InputError(path, "integer out of range");
      }
      return static_cast<int>(u);
    }
    const auto i = value.get<std::int64_t>();
    if (i < std::numeric_limits<int>::min() || i > std::numeric_limits<int>::max()) {
      throw InputError(path, "integer out of range");
    }
    return static_cast<int>(i);
  }
  WrongType(value, path, "an integer");
}

std::uint64_t ReadUint64(const Json& value, const std::string& path) {
  if (value.is_number_unsigned()) return value.get<std::uint64_t>();
  if (value.is_number_integer()) throw InputError(path, "must be >= 0");
  WrongType(value, path, "a non-negative integer");
}

std::string ReadString(const Json& value, const std::string& path) {
  if (!value.is_string()) WrongType(value, path, "a string");
  return value.get<std::string>();
}

Vector ReadVector(const Json& value, const std::string& path, int dimension) {
  ExpectArray(value, path);
  if (dimension > 0 && static_cast<int>(value.size()) != dimension) {
    throw InputError(path, "expected " + std::to_string(dimension) + " components (the scene is " +
                               std::to_string(dimension) + "D), got " +
                               std::to_string(value.size()));
  }
  if (value.empty()) throw InputError(path, "must not be empty");
  Vector v(static_cast<Eigen::Index>(value.size()));
  for (std::size_t a = 0; a < value.size(); ++a) v[a] = ReadNumber(value[a], IndexPath(path, a));
  return v;
}

}  // namespace springfit::proto

namespace springfit::proto {
namespace {

bool IsFlat(const Json& a) {
  for (const Json& e : a) {
    if (e.is_structured()) return false;
  }
  return true;
}

void Dump(const Json& j, int indent, std::string& out) {
  const std::string pad(indent, ' ');
  const std::string inner(indent + 2, ' ');
  if (j.is_object()) {
    if (j.empty()) {
      out += "{}";
      return;
    }
    out += "{\n";
    bool first = true;
    for (const auto& [key, value] : j.items()) {
      if (!first) out += ",\n";
      first = false;
      out += inner + Json(key).dump() + ": ";
      Dump(value, indent + 2, out);
    }
    out += "\n" + pad + "}";
  } else if (j.is_array()) {
    if (IsFlat(j)) {
      out += "[";
      for (std::size_t i = 0; i < j.size(); ++i) {
        if (i) out += ", ";
        out += j[i].dump(-1, ' ', false, Json::error_handler_t::replace);
      }
      out += "]";
      return;
    }
    out += "[\n";
    for (std::size_t i = 0; i < j.size(); ++i) {
      if (i) out += ",\n";
      out += inner;
      Dump(j[i], indent + 2, out);
    }
    out += "\n" + pad + "]";
  } else {
    out += j.dump(-1, ' ', false, Json::error_handler_t::replace);
  }
}

}  // namespace

std::string DumpCompact(const Json& json) {
  std::string out;
  Dump(json, 0, out);
  out += "\n";
  return out;
}

Json NumberOrText(double x) {
  if (std::isfinite(x)) return x;
  if (std::isnan(x)) return "nan";
  return x > 0.0 ? "inf" : "-inf";
}

}  // namespace springfit::proto
