#include "client/progress_line.h"

#include <sys/ioctl.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace springfit::cli {

std::string ClockText(double seconds) {
  if (!(seconds >= 0.0) || !std::isfinite(seconds)) return "-";
  const long long total = std::llround(seconds);
  char text[48];
  if (total < 3600) {
    std::snprintf(text, sizeof text, "%lld:%02lld", total / 60, total % 60);
  } else {
    std::snprintf(text, sizeof text, "%lld:%02lld:%02lld", total / 3600, total / 60 % 60,
                  total % 60);
  }
  return text;
}

std::string FitToWidth(const std::string& line, int columns) {
  const std::size_t room = columns > 4 ? static_cast<std::size_t>(columns - 1) : 3;
  if (line.size() <= room) return line;
  return line.substr(0, room - 3) + "...";
}

namespace {

int TerminalColumns() {
  winsize size{};
  if (::ioctl(fileno(stderr), TIOCGWINSZ, &size) == 0 && size.ws_col > 0) return size.ws_col;
  if (const char* env = std::getenv("COLUMNS")) {
    const int c = std::atoi(env);
    if (c > 0) return c;
  }
  return 80;
}

}  // namespace

ProgressLine::ProgressLine(int max_generations, bool quiet, bool fit)
    : max_generations_(max_generations),
      quiet_(quiet),
      fit_(fit),
      terminal_(isatty(fileno(stderr)) != 0),
      columns_(terminal_ ? TerminalColumns() : 80) {}

void ProgressLine::Report(const TraceRow& row, bool last) {
  if (quiet_) return;
  const double interval = terminal_ ? 0.1 : 2.0;
  if (!last && row.generation != 0 && !shown_beat_ && row.wall_seconds - shown_at_ < interval)
    return;
  shown_beat_ = false;
  if (last && !terminal_ && row.generation == shown_generation_) return;  // already printed
  shown_at_ = row.wall_seconds;
  shown_generation_ = row.generation;
  if (fit_) {
    char line[160];
    std::snprintf(line, sizeof line, "fit step %lld  E %.4g  %.1f s",
                  static_cast<long long>(row.evaluations), std::sqrt(row.best_normalized_error),
                  row.wall_seconds);
    Show(line, last);
    return;
  }
  const double rate =
      row.wall_seconds > 0.0 ? static_cast<double>(row.evaluations) / row.wall_seconds : 0.0;
  std::string topology;
  if (row.missing >= 0)
    topology = "  missing " + std::to_string(row.missing) + " extra " + std::to_string(row.extra);
  // The generation limit's ETA: an upper bound, since reaching the target stops sooner.
  std::string eta;
  if (!last && row.generation > 0 && row.generation < max_generations_) {
    eta = "  ETA <= " +
          ClockText(row.wall_seconds / row.generation * (max_generations_ - row.generation));
  }
  // The most telling first, so that a narrow terminal cuts the least: progress, E (the one
  // error measure shown, proto/RUN.md), the topology's distance, time and ETA, then the
  // evaluation rate.
  char line[320];
  std::snprintf(line, sizeof line, "gen %d/%d  E %.4g%s  %s%s  %.0f eval/s", row.generation,
                max_generations_, std::sqrt(row.best_normalized_error), topology.c_str(),
                ClockText(row.wall_seconds).c_str(), eta.c_str(), rate);
  Show(line, last);
}

void ProgressLine::Show(const char* line, bool last) const {
  if (terminal_) {
    // Cut to the width: a wrapped line cannot be redrawn in place (\r returns to its last row).
    std::fprintf(stderr, "\r\033[K%s%s", FitToWidth(line, columns_).c_str(), last ? "\n" : "");
  } else {
    std::fprintf(stderr, "%s\n", line);
  }
  std::fflush(stderr);
}

void ProgressLine::Beat(const ProgressBeat& beat) {
  if (quiet_) return;
  // Beats come about once a second: a terminal shows each, a log one every two seconds.
  // (A new phase starts its own clock: its first beat is shown.)
  if (!terminal_ && shown_beat_ && beat.phase == shown_phase_ &&
      beat.wall_seconds - shown_at_ < 2.0)
    return;
  shown_phase_ = std::string(beat.phase);
  char line[320];
  if (beat.phase == "genetic" && !std::isnan(beat.best_normalized_error)) {
    std::snprintf(line, sizeof line,
                  "generation %d/%d in progress  E %.4g  %lld evaluations  %.1f s", beat.generation,
                  max_generations_, std::sqrt(beat.best_normalized_error),
                  static_cast<long long>(beat.evaluations), beat.wall_seconds);
  } else if (beat.phase == "fit" && !std::isnan(beat.best_normalized_error)) {
    std::snprintf(line, sizeof line, "fit step %lld in progress  E %.4g  %.1f s",
                  static_cast<long long>(beat.evaluations), std::sqrt(beat.best_normalized_error),
                  beat.wall_seconds);
  } else if (beat.phase == "path" && !std::isnan(beat.best_normalized_error)) {
    std::snprintf(line, sizeof line, "sparsity path: %d points, the last at E %.4g  %.1f s",
                  beat.generation, std::sqrt(beat.best_normalized_error), beat.wall_seconds);
  } else if (beat.phase == "genetic") {
    std::snprintf(line, sizeof line,
                  "generation 0/%d: evaluating the initial population  %lld evaluations  %.1f s",
                  max_generations_, static_cast<long long>(beat.evaluations), beat.wall_seconds);
  } else {
    std::snprintf(line, sizeof line, "%s phase  %.1f s", std::string(beat.phase).c_str(),
                  beat.wall_seconds);
  }
  shown_at_ = beat.wall_seconds;
  shown_beat_ = true;
  Show(line, false);
}

}  // namespace springfit::cli
