// Numbers in text files: as the model writers put them, and as the readers take them.
#pragma once

#include <charconv>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

namespace springfit::io {

// The shortest text that reads back as the same double.
inline std::string ExactNumber(double x) {
  char buffer[32];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, x);
  return ec == std::errc() ? std::string(buffer, end) : std::string("nan");
}

// The finite number `text` holds, all of it (leading spaces, as in fixed-width fields, and
// trailing ones allowed); nullopt for anything else.
inline std::optional<double> NumberIn(const std::string& text) {
  std::size_t used = 0;
  double value = 0.0;
  try {
    value = std::stod(text, &used);
  } catch (const std::exception&) {
    return std::nullopt;
  }
  while (used < text.size() && text[used] == ' ') ++used;
  if (used != text.size() || !std::isfinite(value)) return std::nullopt;
  return value;
}

}  // namespace springfit::io
