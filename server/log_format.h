// The daemon's log lines: user text (labels, scene names, errors that quote them) can hold
// anything, so every line's message is escaped and cut to a bound where it is formatted, in
// one place for every log call: a label with a newline cannot forge a second line, and a
// 10 MB scene name does not write 10 MB of log.
#pragma once
#include <cstddef>
#include <string>
#include <string_view>

namespace springfit::server {

inline constexpr std::size_t kMaxLogMessageBytes = 2000;

// Control characters as \n, \r, \t or \xHH, a backslash doubled; longer than `max` bytes:
// the first `max` and "... (N bytes)".
std::string EscapeLogText(std::string_view text, std::size_t max = kMaxLogMessageBytes);

// spdlog's default logger writes "TIME LEVEL MESSAGE" with the message escaped.
void InstallLogFormat();

}  // namespace springfit::server
