// Progress of a search on standard error: a live line redrawn in place on a terminal, plain
// lines every two seconds otherwise. `springfit run` feeds it every generation and every beat
// inside a step (at least one a second), `springfit watch` every job.progress notification.
#pragma once
#include <string>

#include "engine/api/identify.h"
#include "proto/job.h"

namespace springfit::cli {

// A duration for people (proto/job.h).
using proto::ClockText;

// `line` cut to fit a terminal `columns` wide without wrapping (columns - 1 characters: a
// terminal's last column moves the cursor on), "..." marking the cut. Lines are ASCII.
std::string FitToWidth(const std::string& line, int columns);

class ProgressLine {
 public:
  // `fit`: the run is strategy continuous, whose rows are steps of its fit, not generations.
  ProgressLine(int max_generations, bool quiet, bool fit = false);
  // `last`: the final row (ends the live line).
  void Report(const TraceRow& row, bool last);
  // Inside a step: the generation in progress as far as it has got, or the phase before the
  // genetic one (analysis, direct) with its clock.
  void Beat(const ProgressBeat& beat);

 private:
  // Redrawn in place on a terminal (`last` ends the line), a line of its own otherwise.
  void Show(const std::string& line, bool last) const;

  int max_generations_;
  bool quiet_;
  bool fit_;
  bool terminal_;
  int columns_ = 80;  // the terminal's width (TIOCGWINSZ, else $COLUMNS, else 80)
  double shown_at_ = 0.0;
  int shown_generation_ = -1;
  bool shown_beat_ = false;  // a beat was shown since the last row
  std::string shown_phase_;  // of the last beat shown
};

}  // namespace springfit::cli
