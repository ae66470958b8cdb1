// The size and encoding time of a daemon job's checkpoint as its search goes on
// (bench/RESULTS.md, "Control within a second"):
//
//   build/bench/checkpoint_bench --scene kidney-2d --strategy paper --generations 1000
//
// Runs the search in this process and encodes a checkpoint (server/jobs/checkpoint_codec.h) every
// `--every` generations, as the daemon would every 10 s.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <string>

#include "engine/identification/identify.h"
#include "io/example_catalog.h"
#include "proto/names.h"
#include "server/jobs/checkpoint_codec.h"

int main(int argc, char** argv) {
  using namespace springfit;
  CLI::App app("checkpoint size against generations");
  std::string scene = "kidney-2d";
  std::string strategy = "paper";
  int generations = 1000;
  int every = 250;
  app.add_option("--scene", scene, "Example scene")->capture_default_str();
  app.add_option("--strategy", strategy, "Strategy")->capture_default_str();
  app.add_option("--generations", generations, "Generations to run")->capture_default_str();
  app.add_option("--every", every, "Generations between checkpoints")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);

  const Problem p = Problem::Build(examples::Make(scene));
  SearchSettings settings = p.scene().search;
  settings.strategy = proto::StrategyFromName(strategy, "--strategy");
  SearchOptions o = ResolveSearchOptions(settings, p.gene_count());
  o.max_generations = generations;
  o.stop_at_target = false;
  o.stall_generations = 0;
  const std::uint64_t fingerprint = server::OptionsFingerprint(o);
  RunContext run;
  run.threads = 2;
  std::printf(
      "| generation | evaluations | checkpoint bytes | encode ms |\n|---:|---:|---:|---:|\n");
  run.on_iteration = [&](const TraceRow& row, const IterationState& state) {
    if (state.snapshot && (row.generation % every == 0 || state.finished)) {
      const auto start = std::chrono::steady_clock::now();
      const std::string bytes =
          server::EncodeCheckpoint(state.snapshot(), p.gene_count(), fingerprint);
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
              .count();
      std::printf("| %d | %lld | %zu | %.2f |\n", row.generation,
                  static_cast<long long>(row.evaluations), bytes.size(), ms);
    }
    return true;
  };
  RunIdentification(p, o, run);
  return 0;
}
