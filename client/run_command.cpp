// springfit run SCENE [options]: a topology identification in this process (proto/RUN.md).

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <thread>

#include <unistd.h>

#include "client/commands.h"
#include "client/error_reporting.h"
#include "client/exit_codes.h"
#include "client/progress_line.h"
#include "client/result_summary.h"
#include "client/scene_input.h"
#include "client/search_flags.h"
#include "engine/api/identify.h"
#include "engine/api/input_error.h"
#include "engine/api/problem.h"
#include "proto/names.h"
#include "proto/scene_codec.h"
#include "proto/search_codec.h"

namespace springfit::cli {
namespace {

std::atomic<bool> g_interrupted{false};

// The first signal asks the search to stop after its generation; the default action is
// restored so that a second one ends the process at once.
extern "C" void OnInterrupt(int signal) {
  g_interrupted.store(true);
  std::signal(signal, SIG_DFL);
  // At once, from the handler: write(2) is async-signal-safe, stdio is not.
  static const char kAck[] =
      "\nspringfit: stopping within a second; the best so far is kept (again to quit at once)\n";
  [[maybe_unused]] const auto written = write(STDERR_FILENO, kAck, sizeof kAck - 1);
}

struct RunArgs {
  SceneInput scene;
  SearchFlags search;
  int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::optional<int> population;
  std::optional<double> crossover;
  std::optional<double> mutation;
  std::optional<double> target;
  bool json = false;
  bool quiet = false;
  std::string trace_path;
  std::string output_path;
};

int Run(const RunArgs& args) {
  const auto started = std::chrono::steady_clock::now();  // --time-limit counts from here
  Scene scene = SceneOf(args.scene);
  SearchSettings& st = scene.search;
  ApplySearchFlags(args.search, st);
  if (args.population) st.population = *args.population;
  if (args.crossover) st.crossover_probability = *args.crossover;
  if (args.mutation) st.mutation_probability = *args.mutation;
  if (args.target) st.target_normalized_error = *args.target;
  const Problem problem = Problem::Build(std::move(scene));
  const SearchOptions options = ResolveSearchOptions(problem.scene().search, problem.gene_count());
  for (const std::string& notice : SceneNotices(problem))
    std::fprintf(stderr, "springfit: notice: %s\n", notice.c_str());

  // The result file is written at the end: a name that cannot be written is said now, not
  // after a run of hours (opened to append, and removed again if this made it).
  if (!args.output_path.empty()) {
    const bool existed = std::filesystem::exists(args.output_path);
    {
      std::ofstream probe(args.output_path, std::ios::app);
      if (!probe) throw std::runtime_error("cannot write the result file " + args.output_path);
    }
    if (!existed) std::filesystem::remove(args.output_path);
  }
  std::ofstream trace;
  if (!args.trace_path.empty()) {
    trace.open(args.trace_path);
    if (!trace) throw std::runtime_error("cannot write the trace file " + args.trace_path);
    trace << proto::TraceCsvHeader() << "\n";
  }
  ProgressLine progress(
      options.max_generations, args.quiet,
      ResolvedStrategy(options.strategy, problem.scene()) == Strategy::kContinuous);
  g_interrupted.store(false);
  auto previous_int = std::signal(SIGINT, OnInterrupt);
  auto previous_term = std::signal(SIGTERM, OnInterrupt);

  RunContext run;
  run.started = started;
  run.threads = args.threads;
  run.on_iteration = [&](const TraceRow& row, const IterationState& state) {
    if (trace.is_open()) trace << proto::TraceRowToCsv(row) << std::endl;  // on disk as it goes
    progress.Report(row, state.finished);
    return !g_interrupted.load();
  };
  run.on_beat = [&](const ProgressBeat& beat) {
    progress.Beat(beat);
    return !g_interrupted.load();
  };
  if (!args.quiet) {
    // At once: the first step (a direct phase, generation 0) can take seconds on large scenes.
    std::fprintf(
        stderr, "springfit: %s: strategy %s, %d genes: running\n",
        problem.scene().name.empty() ? args.scene.path.c_str() : problem.scene().name.c_str(),
        std::string(proto::StrategyName(options.strategy)).c_str(), problem.gene_count());
    std::fflush(stderr);
  }
  const IdentificationResult result = RunIdentification(problem, options, run);
  std::signal(SIGINT, previous_int);
  std::signal(SIGTERM, previous_term);
  // A stop inside a step leaves the live line open: end it with the last row.
  if ((result.stop == StopReason::kCancelled || result.stop == StopReason::kTimeLimit) &&
      !result.trace.empty())
    progress.Report(result.trace.back(), true);
  if (trace.is_open()) {
    trace.close();
    if (!trace) throw std::runtime_error("cannot write the trace file " + args.trace_path);
  }

  if (!args.output_path.empty()) {
    WriteResultFile(args.output_path, proto::ResultToJson(problem, result, true),
                    proto::SceneToJson(problem.scene()));
  }
  proto::Json j = proto::ResultToJson(problem, result, false);
  if (args.json) j["threads"] = args.threads;
  PrintResult(j, args.json);
  if (result.stop == StopReason::kCancelled) return kExitInterrupted;
  return ExitCodeOfVerdict(result.outcome.verdict);
}

}  // namespace

void RegisterRun(CLI::App& app, int& exit_code) {
  auto* cmd = app.add_subcommand("run", "Identify the topology: run a search in this process");
  auto args = std::make_shared<RunArgs>();
  AddSceneInput(cmd, args->scene);
  AddSearchFlags(cmd, args->search);
  cmd->add_option("--threads", args->threads,
                  "Threads for the fitness evaluations (the result does not depend on it)")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  cmd->add_option("--population", args->population,
                  "Individuals per generation (default: the strategy's)")
      ->check(CLI::Range(2, 1000000));
  cmd->add_option("--crossover", args->crossover,
                  "Crossover probability per pair (default: the strategy's)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--mutation", args->mutation,
                  "Bit-flip probability per gene (default: the strategy's)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--target", args->target,
                  "Stop at this normalized error (default 0: exact recovery)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--json", args->json,
                "Print one JSON object (proto/RUN.md) instead of the summary");
  cmd->add_flag("-q,--quiet", args->quiet, "No progress lines on standard error");
  cmd->add_option("--trace", args->trace_path,
                  "Write the trace, one CSV row per generation (proto/RUN.md)");
  cmd->add_option("-o,--output", args->output_path,
                  "Write the result with its trace as JSON (proto/RUN.md)");
  cmd->callback([args, &exit_code] {
    exit_code = RunReportingErrors(args->scene.path, [&] { return Run(*args); });
  });
}

}  // namespace springfit::cli
