// Numbers in text files: as the model writers put them, and as the readers take them.
#pragma once

#include <cctype>
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

// A file name's extension in lower case (".INP" reads as ".inp").
inline std::string LowerExtension(const std::string& path) {
  const auto dot = path.find_last_of('.');
  const auto slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string ext = path.substr(dot);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
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
