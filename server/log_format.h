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

// Flushes the log before the process ends at once. The loggers stay registered and usable:
// another thread may be inside a log call or about to make one, and spdlog::shutdown() would
// free the logger under it (a SIGSEGV instead of the exit code; issue 48, item 5).
void FlushLogForExit();

// Ends the process at once with `code` (a second signal, jobs that outlast the shutdown's
// wait) after FlushLogForExit.
[[noreturn]] void FlushLogAndExit(int code);

}  // namespace springfit::server
