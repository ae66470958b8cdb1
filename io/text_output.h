// Numbers as the model writers put them in text files.
#pragma once

#include <charconv>
#include <string>

namespace springfit::io {

// The shortest text that reads back as the same double.
inline std::string ExactNumber(double x) {
  char buffer[32];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, x);
  return ec == std::errc() ? std::string(buffer, end) : std::string("nan");
}

}  // namespace springfit::io
