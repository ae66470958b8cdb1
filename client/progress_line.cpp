#include "client/progress_line.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <string>

namespace springfit::cli {

ProgressLine::ProgressLine(int max_generations, bool quiet, bool fit)
    : max_generations_(max_generations),
      quiet_(quiet),
      fit_(fit),
      terminal_(isatty(fileno(stderr)) != 0) {}

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
    char text[48];
    std::snprintf(text, sizeof text, "  ETA <= %.0f s",
                  row.wall_seconds / row.generation * (max_generations_ - row.generation));
    eta = text;
  }
  char line[320];
  std::snprintf(line, sizeof line,
                "generation %d/%d  best cost %.4g  normalized error %.4g%s  %.0f eval/s  %.1f s%s",
                row.generation, max_generations_, row.best_cost, row.best_normalized_error,
                topology.c_str(), rate, row.wall_seconds, eta.c_str());
  Show(line, last);
}

void ProgressLine::Show(const char* line, bool last) const {
  if (terminal_) {
    std::fprintf(stderr, "\r\033[K%s%s", line, last ? "\n" : "");
  } else {
    std::fprintf(stderr, "%s\n", line);
  }
  std::fflush(stderr);
}

void ProgressLine::Beat(const ProgressBeat& beat, double reference_norm2) {
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
                  "generation %d/%d in progress  best cost %.4g  normalized error %.4g  %lld "
                  "evaluations  %.1f s",
                  beat.generation, max_generations_, beat.best_normalized_error * reference_norm2,
                  beat.best_normalized_error, static_cast<long long>(beat.evaluations),
                  beat.wall_seconds);
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
