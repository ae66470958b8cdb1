// Strict reading of JSON values with errors that name the JSON path.
//
// Every accessor takes the path of the value it reads ("load_cases[2].forces[0].node") and
// throws springfit::InputError with that path when the value has the wrong type, is not
// finite, or is out of the representable range. Objects are read with ExpectKeys() first, so
// that an unknown (misspelt) field is an error rather than silently ignored.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/api/scene.h"

namespace springfit::proto {

// Objects keep their keys in insertion order, so written files read in a sensible order.
using Json = nlohmann::ordered_json;

std::string JoinPath(const std::string& path, std::string_view key);
std::string IndexPath(const std::string& path, std::size_t index);

// Parses text as one JSON document; throws InputError (path empty) with line and column.
Json ParseJson(std::string_view text);

// Requires `value` to be an object whose keys all appear in `allowed`.
void ExpectKeys(const Json& value, const std::string& path,
                std::initializer_list<std::string_view> allowed);
// The member `key` of the object `value`; InputError("path.key", "required") when absent.
const Json& RequiredMember(const Json& value, const std::string& path, std::string_view key);
void ExpectArray(const Json& value, const std::string& path);
void ExpectObject(const Json& value, const std::string& path);

double ReadNumber(const Json& value, const std::string& path);  // finite

// A number to write: itself when finite, else the string "inf", "-inf" or "nan" (JSON has no
// non-finite numbers, and nlohmann would write null, which reads as "absent"). proto/RUN.md
// names the fields that can carry them.
Json NumberOrText(double x);
int ReadInt(const Json& value, const std::string& path);  // an integer within int range
std::uint64_t ReadUint64(const Json& value, const std::string& path);
// The input's own numbers of `count` things (a mesh's node or element tags): an array of
// integers, one per thing, in their order (`what` names them in the count's message).
std::vector<long long> ReadTags(const Json& value, const std::string& path, std::size_t count,
                                std::string_view what);
std::string ReadString(const Json& value, const std::string& path);
// An array of `dimension` finite numbers; dimension 0 accepts any length >= 1.
Vector ReadVector(const Json& value, const std::string& path, int dimension);

// An array whose elements `read_one(element, element_path)` turns into T, in order.
template <typename T, typename ReadOne>
std::vector<T> ReadArray(const Json& value, const std::string& path, ReadOne read_one) {
  ExpectArray(value, path);
  std::vector<T> out;
  out.reserve(value.size());
  for (std::size_t m = 0; m < value.size(); ++m)
    out.push_back(read_one(value[m], IndexPath(path, m)));
  return out;
}

}  // namespace springfit::proto

namespace springfit::proto {

// Pretty-prints with two-space indentation, but keeps arrays of scalars (a node, a pair, a
// force) on one line: a scene of a thousand nodes stays a thousand lines, not four thousand.
std::string DumpCompact(const Json& json);

}  // namespace springfit::proto
