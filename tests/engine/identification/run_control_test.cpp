// Control of a run in every phase (engine/runtime/interruption.h,
// engine/identification/run_monitor.h): beats name their phase, a refused beat or the time limit
// stops the analysis, the direct phase and a first population midway, and the result says what, if
// anything, was found.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <future>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "engine/direct/direct_identification.h"
#include "engine/identification/run_monitor.h"
#include "engine/identification/strategy.h"
#include "engine/problem/baseline_evaluation.h"
#include "engine/runtime/interruption.h"
#include "engine/runtime/worker_pool.h"
#include "io/example_catalog.h"

namespace springfit {
namespace {

TEST(Interruption, PollsOnItsOwnThreadWhenDueAndStaysRequested) {
  int polls = 0;
  bool answer = false;
  Interruption every_time([&] { return ++polls, answer; }, 0.0);
  EXPECT_FALSE(every_time.Check());
  EXPECT_FALSE(every_time.Check());
  EXPECT_EQ(polls, 2);
  // Another thread only reads the flag: the poll (a caller's callback) never runs there.
  std::async(std::launch::async, [&] { EXPECT_FALSE(every_time.Check()); }).get();
  EXPECT_EQ(polls, 2);
  answer = true;
  EXPECT_TRUE(every_time.Check());
  answer = false;
  EXPECT_TRUE(every_time.Check());  // once requested, stays so, without polling again
  EXPECT_EQ(polls, 3);
  std::async(std::launch::async, [&] { EXPECT_TRUE(every_time.Check()); }).get();

  // Not due yet: no poll within the period, nor after Postpone().
  int hourly_polls = 0;
  Interruption hourly([&] { return ++hourly_polls, true; }, 3600.0);
  EXPECT_FALSE(hourly.Check());
  hourly.Postpone();
  EXPECT_FALSE(hourly.Check());
  EXPECT_EQ(hourly_polls, 0);
  hourly.Request();
  EXPECT_TRUE(hourly.Check());
  EXPECT_THROW(ThrowIfInterrupted(&hourly), Interrupted);
  EXPECT_NO_THROW(ThrowIfInterrupted(nullptr));
}

// Sleeps until `flag` is set, 30 s at most (the test's expectations then fail).
void WaitFor(const std::atomic<bool>& flag) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!flag && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
}

TEST(WorkerPool, TheWaitingCallerKeepsCheckingWhileAPoolThreadWorks) {
  WorkerPool pool(2);
  std::atomic<bool> pool_started{false};
  std::atomic<bool> release{false};
  std::atomic<int> checks{0};
  // The caller's slot waits until a pool thread holds the other one; that one blocks until
  // the caller, waiting for it, has checked three times. Without the waiting callback the
  // caller would sleep until the slot ended: 30 s, then the expectations fail.
  auto run = std::async(std::launch::async, [&] {
    const std::thread::id caller = std::this_thread::get_id();
    pool.Run(
        2,
        [&](int) {
          if (std::this_thread::get_id() == caller) {
            WaitFor(pool_started);
          } else {
            pool_started = true;
            WaitFor(release);
          }
        },
        [&] {
          if (++checks >= 3) release = true;
        });
  });
  ASSERT_EQ(run.wait_for(std::chrono::seconds(90)), std::future_status::ready);
  run.get();
  EXPECT_TRUE(pool_started.load());
  EXPECT_GE(checks.load(), 3);
  EXPECT_TRUE(release.load());
}

// Refuses the first beat of `phase` and records every beat's phase.
struct StopAtPhase {
  std::string phase;
  std::vector<std::string> seen;
  RunContext Context() {
    RunContext c;
    c.beat_seconds = 0.0;  // every check polls
    c.on_beat = [this](const ProgressBeat& beat) {
      seen.emplace_back(beat.phase);
      return beat.phase != phase;
    };
    return c;
  }
};

SearchOptions Resolved(const Problem& p, Strategy strategy) {
  SearchSettings s = p.scene().search;
  s.strategy = strategy;
  return ResolveSearchOptions(s, p.gene_count());
}

// `strategy` on `p`, stopped at its first beat in `phase`: the last beat seen is that phase's,
// and the run says it was cancelled.
IdentificationResult StoppedIn(const Problem& p, Strategy strategy, const std::string& phase) {
  StopAtPhase stop{phase, {}};
  IdentificationResult r = RunIdentification(p, Resolved(p, strategy), stop.Context());
  EXPECT_FALSE(stop.seen.empty()) << phase;
  if (!stop.seen.empty()) {
    EXPECT_EQ(stop.seen.back(), phase);
  }
  EXPECT_EQ(r.stop, StopReason::kCancelled) << phase;
  return r;
}

TEST(RunControl, StoppingTheDirectPhaseReturnsNoModel) {
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  const IdentificationResult r = StoppedIn(p, Strategy::kDirect, "direct");
  EXPECT_TRUE(r.trace.empty());
  EXPECT_EQ(std::count(r.best.begin(), r.best.end(), 1), 0);
  EXPECT_EQ(static_cast<int>(r.best.size()), p.gene_count());
  EXPECT_TRUE(r.evaluation.mechanism);  // the empty topology, evaluated
  EXPECT_NE(r.stop_message.find("before any model"), std::string::npos) << r.stop_message;
}

TEST(RunControl, StoppingTheFirstPopulationKeepsTheDirectSeed) {
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  StopAtPhase stop{"genetic", {}};
  const IdentificationResult r =
      RunIdentification(p, Resolved(p, Strategy::kDefault), stop.Context());
  // The phases beat in order: the analysis before the run (the identifiability report), then
  // the direct phase, then the genetic one, where the stop came.
  const auto direct = std::find(stop.seen.begin(), stop.seen.end(), "direct");
  ASSERT_NE(direct, stop.seen.end());
  EXPECT_TRUE(std::all_of(stop.seen.begin(), direct,
                          [](const std::string& phase) { return phase == "analysis"; }));
  EXPECT_EQ(stop.seen.back(), "genetic");
  EXPECT_EQ(r.stop, StopReason::kCancelled);
  EXPECT_TRUE(r.trace.empty());
  ASSERT_TRUE(r.direct_phase);
  DirectOptions topology_only;
  topology_only.known_stiffness = p.training_stiffness();
  EXPECT_EQ(r.best, IdentifyDirect(p, topology_only).genome);
  EXPECT_EQ(r.evaluation.normalized_error, r.direct_phase->normalized_error);
  EXPECT_NE(r.stop_message.find("direct phase's topology is kept"), std::string::npos)
      << r.stop_message;
}

TEST(RunControl, TheTimeLimitStopsInsideTheDirectPhase) {
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  SearchOptions o = Resolved(p, Strategy::kDirect);
  o.max_seconds = 1e-9;
  RunContext c;
  c.beat_seconds = 0.0;
  const IdentificationResult r = RunIdentification(p, o, c);
  EXPECT_EQ(r.stop, StopReason::kTimeLimit);
  EXPECT_TRUE(r.trace.empty());
  EXPECT_NE(r.stop_message.find("time limit"), std::string::npos) << r.stop_message;
  // Without a limit the same run completes with its one row.
  o.max_seconds = 0.0;
  const IdentificationResult whole = RunIdentification(p, o, c);
  EXPECT_NE(whole.stop, StopReason::kTimeLimit);
  EXPECT_EQ(whole.trace.size(), 1u);
}

TEST(RunControl, TheFemBaselineIsStoppableBeforeTheRun) {
  const Problem p = Problem::Build(examples::Make("fem-plate-5x5"));
  StopAtPhase stop{"analysis", {}};
  const IdentificationResult r =
      RunIdentification(p, Resolved(p, Strategy::kDefault), stop.Context());
  ASSERT_EQ(stop.seen.size(), 1u);
  EXPECT_EQ(stop.seen.front(), "analysis");
  EXPECT_EQ(r.stop, StopReason::kCancelled);
  EXPECT_FALSE(r.baseline);  // stopped while evaluating it
  EXPECT_FALSE(r.direct_phase);
  EXPECT_TRUE(r.trace.empty());
  // What comes back is the start the fit would have had, the closed-form baseline, named as
  // such (not "0 springs ... a mechanism", nor "springs fitted").
  const std::vector<double> baseline = *BaselineGeneWeights(p);
  int springs = 0;
  for (double w : baseline) springs += w > 0.0;
  EXPECT_EQ(static_cast<int>(r.springs.size()), springs);
  EXPECT_FALSE(r.evaluation.mechanism);
  EXPECT_NE(
      r.stop_message.find("the closed-form baseline (" + std::to_string(springs) + " springs"),
      std::string::npos)
      << r.stop_message;
  EXPECT_EQ(r.outcome.verdict, Verdict::kUsable);
}

// A stop during the nonlinear judgement (after the fit) returns the fitted model, says it was
// stopped and not judged at amplitudes, and leaves the amplitudes empty rather than partial.
TEST(RunControl, AStopDuringTheNonlinearJudgementIsAStopNotACompletion) {
  const Problem p = Problem::Build(examples::Make("fem-kidney-2d-nl"));
  const IdentificationResult whole =
      RunIdentification(p, Resolved(p, Strategy::kContinuous), RunContext{});
  ASSERT_EQ(whole.stop, StopReason::kCompleted);
  ASSERT_TRUE(whole.generalization);
  ASSERT_FALSE(whole.generalization->amplitudes.empty());
  const IdentificationResult r = StoppedIn(p, Strategy::kContinuous, "nonlinear");
  EXPECT_NE(r.stop_message.find("during the nonlinear judgement"), std::string::npos)
      << r.stop_message;
  ASSERT_TRUE(r.generalization);
  EXPECT_TRUE(r.generalization->amplitudes.empty());
  EXPECT_EQ(r.best, whole.best);  // the fitted model, whole
  EXPECT_EQ(r.stiffness, whole.stiffness);
}

// A stop during the nonlinear fit returns the rest-linear model it started from, uncertified,
// and says so.
TEST(RunControl, AStopDuringTheNonlinearFitReturnsTheRestLinearModel) {
  const Problem p = Problem::Build(examples::Make("fem-kidney-2d-nl"));
  const IdentificationResult whole =
      RunIdentification(p, Resolved(p, Strategy::kContinuous), RunContext{});
  ASSERT_TRUE(whole.generalization && whole.generalization->fit.nonlinear);
  std::vector<double> rest_linear;
  for (double w : whole.generalization->fit.weights)
    if (w > 0.0) rest_linear.push_back(w);
  ASSERT_NE(rest_linear, whole.stiffness);  // (the stage moved it)
  const IdentificationResult r = StoppedIn(p, Strategy::kContinuous, "nonlinear_fit");
  EXPECT_NE(r.stop_message.find("during the nonlinear fit: the rest-linear fitted model"),
            std::string::npos)
      << r.stop_message;
  EXPECT_FALSE(r.generalization);
  EXPECT_EQ(r.stiffness, rest_linear);
}

// A stop during the certificate ends the run there (its solves and Lanczos steps check for it):
// the fitted model comes back uncertified, and says so.
TEST(RunControl, AStopDuringTheCertificateReturnsTheModelUncertified) {
  const Problem p = Problem::Build(examples::Make("fem-kidney-2d"));
  const IdentificationResult whole =
      RunIdentification(p, Resolved(p, Strategy::kContinuous), RunContext{});
  ASSERT_TRUE(whole.generalization);
  const IdentificationResult r = StoppedIn(p, Strategy::kContinuous, "certificate");
  EXPECT_NE(r.stop_message.find("during the certificate"), std::string::npos) << r.stop_message;
  EXPECT_NE(r.stop_message.find("not certified"), std::string::npos) << r.stop_message;
  EXPECT_FALSE(r.generalization);
  EXPECT_EQ(r.best, whole.best);  // the fitted model, whole
  EXPECT_EQ(r.stiffness, whole.stiffness);
}

// A stop during the fit returns the start, named as such: not "springs fitted".
TEST(RunControl, AStopDuringTheFitReturnsTheStartNamedAsTheBaseline) {
  const Problem p = Problem::Build(examples::Make("fem-kidney-2d"));
  const IdentificationResult r = StoppedIn(p, Strategy::kContinuous, "probe_fit");
  EXPECT_NE(r.stop_message.find("during the fit: the start (the closed-form baseline"),
            std::string::npos)
      << r.stop_message;
  EXPECT_EQ(r.stop_message.find("springs fitted"), std::string::npos) << r.stop_message;
  EXPECT_FALSE(r.generalization);
}

// Issue 47 item 3: a time limit that stops the fit returns the start named as the baseline, and
// says how long the fit would have needed at the pace of the steps it made (the machine is slowed
// here, past the limit, once the fit has made a step).
TEST(RunControl, ATimeLimitInTheFitSaysHowLongTheFitWouldNeed) {
  const Problem p = Problem::Build(examples::Make("fem-kidney-2d"));
  SearchOptions o = Resolved(p, Strategy::kContinuous);
  o.max_seconds = 6.0;
  // (A beat carries the fit's best choosing error so far: its third value comes after two
  // reports past the start's, so after at least one step.)
  std::vector<double> errors;
  std::vector<double> etas;  // the beats' estimates of the continuation's time left
  RunContext c;
  c.beat_seconds = 0.0;
  c.on_beat = [&](const ProgressBeat& beat) {
    if (std::string(beat.phase) != "probe_fit" || !std::isfinite(beat.best_normalized_error) ||
        (!errors.empty() && errors.back() == beat.best_normalized_error))
      return true;
    errors.push_back(beat.best_normalized_error);
    etas.push_back(beat.eta_seconds);
    if (errors.size() == 3) std::this_thread::sleep_for(std::chrono::milliseconds(6500));
    return true;
  };
  const IdentificationResult r = RunIdentification(p, o, c);
  ASSERT_EQ(r.stop, StopReason::kTimeLimit) << r.stop_message;
  EXPECT_NE(r.stop_message.find("during the fit: the start (the closed-form baseline"),
            std::string::npos)
      << r.stop_message;
  EXPECT_NE(r.stop_message.find("Gauss-Newton steps in "), std::string::npos) << r.stop_message;
  EXPECT_NE(r.stop_message.find(", of the continuation's at most 21: at that pace up to "),
            std::string::npos)
      << r.stop_message;
  // The limit it names is on the run's clock, the one that stopped it, and above that limit.
  const std::string above = "a time limit above ";
  const std::size_t at = r.stop_message.find(above);
  ASSERT_NE(at, std::string::npos) << r.stop_message;
  EXPECT_GT(std::stod(r.stop_message.substr(at + above.size())), o.max_seconds) << r.stop_message;
  EXPECT_FALSE(r.generalization);
  // The beats said the time left (progress lines and job.phase show it): none before a step
  // (the start's report alone), an estimate after.
  ASSERT_EQ(etas.size(), 3u);
  EXPECT_TRUE(std::isnan(etas[0])) << etas[0];
  EXPECT_TRUE(std::isfinite(etas[2]) && etas[2] > 0.0) << etas[2];
}

TEST(RunControl, AResumedRunStoppedBeforeItsFirstStepKeepsTheCheckpointsBest) {
  const Problem p = Problem::Build(examples::Make("fem-plate-5x5"));
  SearchOptions o = Resolved(p, Strategy::kPaper);
  o.max_generations = 6;
  std::optional<SearchState> snapshot;
  RunContext first;
  first.on_iteration = [&](const TraceRow& row, const IterationState& state) {
    if (row.generation < 3) return true;
    snapshot = state.snapshot();
    return false;
  };
  RunIdentification(p, o, first);
  ASSERT_TRUE(snapshot);
  // Stopped in the analysis (the FEM baseline) before the resumed GA's first step.
  StopAtPhase stop{"analysis", {}};
  RunContext resumed = stop.Context();
  resumed.resume_from = snapshot;
  const IdentificationResult r = RunIdentification(p, o, resumed);
  EXPECT_EQ(r.stop, StopReason::kCancelled);
  EXPECT_EQ(r.best, snapshot->best);
  EXPECT_EQ(r.generations, snapshot->generation);
  EXPECT_EQ(r.evaluation.normalized_error, snapshot->best_fitness.normalized_error);
  EXPECT_NE(r.stop_message.find("checkpoint's best"), std::string::npos) << r.stop_message;
}

// One clock for the time limit (issue 32 item 5): a resumed run's monitor counts the time its
// checkpoint had used, as the GA's clock does, so that a limit already spent stops it at the
// first poll rather than a whole limit later.
TEST(RunControl, AResumedRunsClockGoesOnFromItsCheckpoint) {
  SearchState resumed;
  resumed.elapsed_seconds = 100.0;
  RunContext context;
  context.resume_from = resumed;
  RunMonitor monitor(context, 50.0);
  EXPECT_GE(monitor.SecondsSinceStart(), 100.0);
  EXPECT_TRUE(monitor.TimeLimitPassed());
  EXPECT_TRUE(monitor.time_limit_reached());
  RunContext fresh;
  RunMonitor fresh_monitor(fresh, 50.0);
  EXPECT_LT(fresh_monitor.SecondsSinceStart(), 50.0);
  EXPECT_FALSE(fresh_monitor.TimeLimitPassed());
}

// A time limit bounds what the user waits (issue 48 item 6): it counts from when the run began
// for its user (RunContext::started: the command's start, the job's claim, before the scene is
// prepared), and it trips early by what a stopped run still does after it.
TEST(RunControl, TheTimeLimitCountsFromTheRunsStartAndKeepsRoomForClosing) {
  RunContext prepared_long;
  prepared_long.started = std::chrono::steady_clock::now() - std::chrono::seconds(40);
  RunMonitor late(prepared_long, 30.0);
  EXPECT_GE(late.SecondsSinceStart(), 40.0);
  EXPECT_TRUE(late.TimeLimitPassed());

  RunContext now;
  now.started = std::chrono::steady_clock::now() - std::chrono::seconds(25);
  RunMonitor within(now, 30.0);
  EXPECT_FALSE(within.TimeLimitPassed());
  within.ReserveForClosing(6.0);  // closing takes 6 s: 25 + 6 is past 30
  EXPECT_TRUE(within.TimeLimitPassed());

  // A whole run whose preparation used its limit stops at once, with the start named as such.
  const Problem p = Problem::Build(examples::Make("fem-plate-5x5"));
  SearchOptions o = Resolved(p, Strategy::kDefault);
  o.max_seconds = 5.0;
  const IdentificationResult r = RunIdentification(p, o, prepared_long);
  EXPECT_EQ(r.stop, StopReason::kTimeLimit);
  EXPECT_NE(r.stop_message.find("time limit reached"), std::string::npos) << r.stop_message;
  EXPECT_FALSE(r.generalization);  // not certified
}

TEST(WorkerPool, AThrowingWaitCallbackStillWaitsForTheRunningSlots) {
  WorkerPool pool(2);
  std::atomic<bool> pool_started{false};
  std::atomic<bool> pool_done{false};
  bool done_when_run_returned = false;
  auto run = std::async(std::launch::async, [&] {
    const std::thread::id caller = std::this_thread::get_id();
    try {
      pool.Run(
          2,
          [&](int) {
            if (std::this_thread::get_id() == caller) {
              WaitFor(pool_started);
            } else {
              pool_started = true;
              std::this_thread::sleep_for(std::chrono::milliseconds(300));
              pool_done = true;
            }
          },
          [] { throw std::runtime_error("from the wait callback"); });
    } catch (const std::runtime_error&) {
      done_when_run_returned = pool_done.load();
      return true;
    }
    return false;
  });
  ASSERT_EQ(run.wait_for(std::chrono::seconds(60)), std::future_status::ready);
  EXPECT_TRUE(run.get()) << "the callback's exception was not rethrown";
  EXPECT_TRUE(done_when_run_returned) << "Run returned while a slot was still running";
}

}  // namespace
}  // namespace springfit
