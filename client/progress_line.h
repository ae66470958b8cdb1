// Progress of a search on standard error: a live line redrawn in place on a terminal, plain
// lines every two seconds otherwise. `springfit run` feeds it every generation and every beat
// inside a step (at least one a second), `springfit watch` every job.progress notification.
#pragma once
#include <string>

#include "engine/identification/identify.h"

namespace springfit::cli {

class ProgressLine {
 public:
  // `fit`: the run is strategy continuous, whose rows are steps of its fit, not generations.
  ProgressLine(int max_generations, bool quiet, bool fit = false);
  // `last`: the final row (ends the live line).
  void Report(const TraceRow& row, bool last);
  // Inside a step: the generation in progress as far as it has got, or the phase before the
  // genetic one (analysis, direct) with its clock. `reference_norm2` turns errors into costs.
  void Beat(const ProgressBeat& beat, double reference_norm2);

 private:
  // Redrawn in place on a terminal (`last` ends the line), a line of its own otherwise.
  void Show(const char* line, bool last) const;

  int max_generations_;
  bool quiet_;
  bool fit_;
  bool terminal_;
  double shown_at_ = 0.0;
  int shown_generation_ = -1;
  bool shown_beat_ = false;  // a beat was shown since the last row
  std::string shown_phase_;  // of the last beat shown
};

}  // namespace springfit::cli
