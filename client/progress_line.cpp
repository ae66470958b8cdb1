#include "client/progress_line.h"

#include <sys/ioctl.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <fmt/format.h>

namespace springfit::cli {

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
    Show(fmt::format("fit step {}  E {:.4g}  {:.1f} s", row.evaluations,
                     std::sqrt(row.best_normalized_error), row.wall_seconds),
         last);
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
  Show(fmt::format("gen {}/{}  E {:.4g}{}  {}{}  {:.0f} eval/s", row.generation, max_generations_,
                   std::sqrt(row.best_normalized_error), topology, ClockText(row.wall_seconds), eta,
                   rate),
       last);
}

void ProgressLine::Show(const std::string& line, bool last) const {
  if (terminal_) {
    // Cut to the width: a wrapped line cannot be redrawn in place (\r returns to its last row).
    std::fprintf(stderr, "\r\033[K%s%s", FitToWidth(line, columns_).c_str(), last ? "\n" : "");
  } else {
    std::fprintf(stderr, "%s\n", line.c_str());
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
  std::string line;
  if (beat.phase == "genetic" && !std::isnan(beat.best_normalized_error)) {
    line = fmt::format("generation {}/{} in progress  E {:.4g}  {} evaluations  {:.1f} s",
                       beat.generation, max_generations_, std::sqrt(beat.best_normalized_error),
                       beat.evaluations, beat.wall_seconds);
  } else if (beat.phase == "fit" && !std::isnan(beat.best_normalized_error)) {
    line = fmt::format("fit step {} in progress  E {:.4g}  {:.1f} s", beat.evaluations,
                       std::sqrt(beat.best_normalized_error), beat.wall_seconds);
  } else if (beat.phase == "path" && !std::isnan(beat.best_normalized_error)) {
    line = fmt::format("sparsity path: {} points, the last at E {:.4g}  {:.1f} s", beat.generation,
                       std::sqrt(beat.best_normalized_error), beat.wall_seconds);
  } else if (beat.phase == "genetic") {
    line =
        fmt::format("generation 0/{}: evaluating the initial population  {} evaluations  {:.1f} s",
                    max_generations_, beat.evaluations, beat.wall_seconds);
  } else if (!std::isnan(beat.best_normalized_error)) {
    // (The probe fit's phases: E of its latest model on the probes it chooses by, and the
    // continuation's time left at most where the phase estimates it.)
    line = fmt::format("{} phase  choosing E {:.4g}  {:.1f} s{}", beat.phase,
                       std::sqrt(beat.best_normalized_error), beat.wall_seconds,
                       std::isfinite(beat.eta_seconds) ? "  ETA <= " + ClockText(beat.eta_seconds)
                                                       : std::string());
  } else {
    line = fmt::format("{} phase  {:.1f} s", beat.phase, beat.wall_seconds);
  }
  shown_at_ = beat.wall_seconds;
  shown_beat_ = true;
  Show(line, false);
}

}  // namespace springfit::cli
