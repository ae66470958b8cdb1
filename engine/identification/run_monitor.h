// Progress and stopping of one identification run, whatever the phase it is in.
//
// RunIdentification() makes one RunMonitor per run. Its Interruption
// (engine/runtime/interruption.h) reaches every long loop of the run: the analysis before it, the
// direct phase's solves, the genetic generations' evaluations. When due (RunContext::beat_seconds
// after the last report) the poll describes where the run has got to as a ProgressBeat of the
// current phase, hands it to RunContext::on_beat, and stops the run when that returns false or when
// the time limit (SearchOptions::max_seconds of wall time since the run began) has passed.
#pragma once

#include <chrono>
#include <functional>
#include <string_view>

#include "engine/identification/identify.h"
#include "engine/runtime/interruption.h"
#include "engine/runtime/wall_clock.h"

namespace springfit {

class RunMonitor {
 public:
  RunMonitor(const RunContext& context, double max_seconds);
  RunMonitor(const RunMonitor&) = delete;
  RunMonitor& operator=(const RunMonitor&) = delete;

  Interruption& interruption() { return interruption_; }
  // From now on beats describe `phase`; `fill` completes them (the run's clock, generation,
  // evaluations, best so far). Without `fill` a beat carries the seconds since the run began.
  void SetPhase(std::string_view phase, std::function<void(ProgressBeat&)> fill = {});
  // The caller reported progress (an iteration's row): the next beat is due a period later.
  void Reported() { interruption_.Postpone(); }
  // The run was stopped by its time limit (rather than by the caller).
  bool time_limit_reached() const { return time_limit_reached_; }
  // Checks the time limit now (between iterations, where no poll may be due).
  bool TimeLimitPassed();
  // The run's clock: seconds since it began, a resumed run's earlier seconds included.
  double SecondsSinceStart() const;
  // What the run still does once stopped (its returned model's named cases, solved again): the
  // time limit trips this much earlier, so that the whole run ends within it.
  void ReserveForClosing(double seconds) { closing_seconds_ = seconds; }

 private:
  bool Poll();

  const RunContext& context_;
  double max_seconds_;
  double before_;  // a resumed run's seconds before this process (its checkpoint's clock)
  double closing_seconds_ = 0.0;
  std::chrono::steady_clock::time_point start_;
  std::string_view phase_ = "analysis";
  std::function<void(ProgressBeat&)> fill_;
  bool time_limit_reached_ = false;
  Interruption interruption_;  // last: its poll uses the members above
};

// From now on beats describe `phase` with its own clock alone (seconds since `start`, no error).
void ClockPhase(RunMonitor& monitor, std::string_view phase,
                std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now());

}  // namespace springfit
