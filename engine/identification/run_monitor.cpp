#include "engine/identification/run_monitor.h"

#include <limits>
#include <utility>

namespace springfit {

RunMonitor::RunMonitor(const RunContext& context, double max_seconds)
    : context_(context),
      max_seconds_(max_seconds),
      // A resumed run's clock goes on from its checkpoint, as the GA's does (SearchState::
      // elapsed_seconds): one clock for the time limit, whichever of them checks it.
      before_(context.resume_from ? context.resume_from->elapsed_seconds : 0.0),
      start_(context.started.value_or(std::chrono::steady_clock::now())),
      interruption_([this] { return Poll(); }, context.beat_seconds) {}

void RunMonitor::SetPhase(std::string_view phase, std::function<void(ProgressBeat&)> fill) {
  phase_ = phase;
  fill_ = std::move(fill);
}

double RunMonitor::SecondsSinceStart() const {
  return before_ + SecondsSince(start_);
}

bool RunMonitor::TimeLimitPassed() {
  if (max_seconds_ > 0.0 && SecondsSinceStart() + closing_seconds_ >= max_seconds_)
    time_limit_reached_ = true;
  return time_limit_reached_;
}

bool RunMonitor::Poll() {
  ProgressBeat beat;
  beat.phase = phase_;
  beat.wall_seconds = SecondsSinceStart();
  if (fill_)
    fill_(beat);
  else
    beat.best_normalized_error = std::numeric_limits<double>::quiet_NaN();  // no model: no E
  // The time limit is on the wall clock from the run's start, its analysis included: what a
  // user who asked for it waits (the trace's clock starts after the analysis).
  if (TimeLimitPassed()) return true;
  return context_.on_beat && !context_.on_beat(beat);
}

void ClockPhase(RunMonitor& monitor, std::string_view phase,
                std::chrono::steady_clock::time_point start) {
  monitor.SetPhase(phase, [start](ProgressBeat& beat) {
    beat.wall_seconds = SecondsSince(start);
    beat.best_normalized_error = std::numeric_limits<double>::quiet_NaN();
  });
}

}  // namespace springfit
