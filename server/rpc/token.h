// The daemon's token check, shared by the JSON-RPC session.auth and the dashboard.
#pragma once
#include <string>

namespace springfit::server {

// Takes a time that depends only on the length of the token given, not on how much of it
// is right.
inline bool SameToken(const std::string& expected, const std::string& given) {
  std::size_t diff = expected.size() ^ given.size();
  for (std::size_t i = 0; i < given.size(); ++i) {
    const auto e = static_cast<unsigned char>(i < expected.size() ? expected[i] : 0);
    diff |= static_cast<unsigned char>(e ^ static_cast<unsigned char>(given[i]));
  }
  return diff == 0;
}

}  // namespace springfit::server
