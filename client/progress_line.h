// Progress of a search on standard error: a live line redrawn in place on a terminal, plain
// lines every two seconds otherwise. `springfit run` feeds it every generation, `springfit
// watch` every job.progress notification.
#pragma once
#include "engine/search/genetic_search.h"

namespace springfit::cli {

class ProgressLine {
 public:
  ProgressLine(int max_generations, bool quiet);
  // `last`: the final row (ends the live line).
  void Report(const TraceRow& row, bool last);

 private:
  int max_generations_;
  bool quiet_;
  bool terminal_;
  double shown_at_ = 0.0;
  int shown_generation_ = -1;
};

}  // namespace springfit::cli
