// The paper's experiment, reproduced and timed: every strategy on every scene over many
// seeds; success rate, time to exact recovery and the error reached against wall time.
// Prints the markdown tables of bench/RESULTS.md ("Topology search", issue 3).
//
//   build/bench/search_experiment [--seeds N] [--threads N] [--time-limit S]
//                                 [--scenes a,b] [--strategies paper,default]
//   build/bench/search_experiment --full-run paper-iso-5x5   (1000 generations, no early stop)
//   build/bench/search_experiment --elites 1 ...            (a variant: strategies with N elites)
//   build/bench/search_experiment --roulette-exponent 2 ... (a variant: roulette weights e^-2)
//   build/bench/search_experiment --local-optima ...        (also: can single flips or pairs
//        of flips improve the best genome of each run that was not exact?)
//   build/bench/search_experiment --strategies paper,default,direct,hybrid --noise 0.01
//        (noisy references: seed s also draws the noise; exactness against the clean scene)
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include "engine/identification/strategy.h"
#include "engine/problem/cost.h"
#include "io/example_catalog.h"
#include "proto/names.h"

namespace springfit {
namespace {

constexpr double kCheckpoints[] = {1e-3, 1e-2, 1e-1, 1.0, 10.0};

struct RunRecord {
  bool exact = false;
  int generations = 0;
  std::int64_t evaluations = 0;
  double seconds = 0.0;
  double final_error = 0.0;
  int missing = 0;
  int extra = 0;
  std::vector<double> error_at;  // per checkpoint; NaN = not yet evaluated the first generation
  Genome best;
};

// How a genome's neighbourhood compares with it: single flips that lower its normalised
// error, and, when none does, pairs of flips that do (-1: not examined, the genome has more
// than kMaxGenesForPairs genes).
struct Neighbourhood {
  int improving_flips = 0;
  int improving_pairs = 0;
};

// All pairs of a 5x5 scene's 72 genes are 2,556 evaluations; a 461-gene scene's would be
// 106,030, minutes per run.
constexpr int kMaxGenesForPairs = 100;

Neighbourhood ExamineNeighbourhood(const Problem& problem, const Genome& genome) {
  CostFunction cost(problem);
  const double e = cost.EvaluateGenome(genome).normalized_error;
  const auto improves = [&](Genome g, int a, int b) {
    g[static_cast<std::size_t>(a)] ^= 1;
    if (b >= 0) g[static_cast<std::size_t>(b)] ^= 1;
    return cost.EvaluateGenome(g).normalized_error < e;
  };
  Neighbourhood n;
  const int genes = static_cast<int>(genome.size());
  for (int a = 0; a < genes; ++a) n.improving_flips += improves(genome, a, -1);
  if (n.improving_flips > 0) return n;
  if (genes > kMaxGenesForPairs) {
    n.improving_pairs = -1;
    return n;
  }
  for (int a = 0; a < genes; ++a) {
    for (int b = a + 1; b < genes; ++b) n.improving_pairs += improves(genome, a, b);
  }
  return n;
}

std::vector<std::string> Split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  for (std::string item; std::getline(in, item, ',');) out.push_back(item);
  return out;
}

double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const auto hi = static_cast<std::size_t>(std::ceil(pos));
  return v[lo] + (v[hi] - v[lo]) * (pos - static_cast<double>(lo));
}

std::string Seconds(double s) {
  if (std::isnan(s)) return "—";
  if (s < 1e-3) return fmt::format("{:.0f} µs", s * 1e6);
  if (s < 1.0) return fmt::format("{:.1f} ms", s * 1e3);
  return fmt::format("{:.2f} s", s);
}

// `precision` digits: ".3g" (significant) or ".0f" / ".1f" (fixed), fmt's format specs.
std::string Number(double x, const char* precision = ".3g") {
  if (std::isnan(x)) return "—";
  return fmt::format(fmt::runtime(std::string("{:") + precision + "}"), x);
}

// Overrides of a strategy's operators, for the experiments on the paper's unpublished choices.
struct Variant {
  int elites = -1;                 // < 0: the strategy's
  double roulette_exponent = 0.0;  // <= 0: the strategy's (roulette strategies only)
  bool any() const { return elites >= 0 || roulette_exponent > 0.0; }
};

// `truth`: the problem whose reference topology judges exactness (the clean scene of a noisy
// one; the problem itself otherwise).
RunRecord RunOnce(const Problem& problem, const Problem& truth, Strategy strategy,
                  std::uint64_t seed, int threads, double time_limit, const Variant& variant,
                  bool topology_only, bool no_direct_seed) {
  SearchOptions o = StrategyDefaults(strategy, problem.gene_count());
  if (topology_only) o.identify = Identify::kTopology;
  o.seed = seed;
  if (variant.elites >= 0) o.elites = variant.elites;
  if (variant.roulette_exponent > 0.0) o.roulette_exponent = variant.roulette_exponent;
  RunContext run;
  run.threads = threads;
  run.on_iteration = [&](const TraceRow& row, const IterationState&) {
    return row.wall_seconds < time_limit;
  };
  // default-ga: the memetic GA of `default` alone, without its direct seed.
  IdentificationResult r = no_direct_seed ? RunIdentification(problem, o, run, GeneticStrategy())
                                          : RunIdentification(problem, o, run);
  r.difference = truth.CompareWithReference(r.best);
  RunRecord rec;
  rec.exact = r.exact().value_or(false);
  rec.generations = r.generations;
  rec.evaluations = r.counters.evaluations;
  rec.seconds = r.trace.back().wall_seconds;
  rec.final_error = r.evaluation.normalized_error;
  rec.best = r.best;
  rec.missing = r.difference ? static_cast<int>(r.difference->missing.size()) : -1;
  rec.extra = r.difference ? static_cast<int>(r.difference->extra.size()) : -1;
  for (double t : kCheckpoints) {
    double e = NAN;
    for (const TraceRow& row : r.trace) {
      if (row.wall_seconds > t) break;
      e = row.best_normalized_error;
    }
    // A run that ended before t keeps its final error (0 when exact).
    if (r.trace.back().wall_seconds <= t) e = r.trace.back().best_normalized_error;
    rec.error_at.push_back(e);
  }
  return rec;
}

int FullRun(const std::string& scene, int threads, int repeats) {
  const Problem problem = Problem::Build(examples::Make(scene));
  for (Strategy strategy : {Strategy::kPaper, Strategy::kDefault}) {
    std::vector<double> seconds;
    std::int64_t evaluations = 0, hits = 0;
    for (int i = 0; i < repeats; ++i) {
      SearchOptions o = StrategyDefaults(strategy, problem.gene_count());
      o.seed = static_cast<std::uint64_t>(i + 1);
      o.stop_at_target = false;
      RunContext run;
      run.threads = threads;
      // The GA alone (no direct seed): its own throughput, comparable across strategies.
      const IdentificationResult r = RunIdentification(problem, o, run, GeneticStrategy());
      seconds.push_back(r.wall_seconds);
      evaluations += r.counters.evaluations;
      hits += r.counters.cache_hits;
    }
    std::printf("| %s | %s | %d | %s | %s | %.0f | %.0f%% |\n", scene.c_str(),
                strategy == Strategy::kPaper ? "paper" : "default-ga", threads,
                Seconds(Quantile(seconds, 0.5)).c_str(),
                Seconds(*std::max_element(seconds.begin(), seconds.end())).c_str(),
                static_cast<double>(evaluations) / repeats,
                100.0 * static_cast<double>(hits) / static_cast<double>(evaluations));
  }
  return 0;
}

int Main(int argc, char** argv) {
  CLI::App app{"springfit search experiment (bench/RESULTS.md)"};
  int seeds = 20, threads = 2, repeats = 5;
  Variant variant;
  bool local_optima = false;
  double time_limit = 10.0;
  std::string scenes = "paper-iso-5x5,paper-aniso-5x5,kidney-2d,grid3d-4x4x4";
  std::string strategies = "paper,default";
  std::string full_run;
  double noise = 0.0;
  app.add_option("--seeds", seeds)->capture_default_str();
  app.add_option("--threads", threads)->capture_default_str();
  app.add_option("--time-limit", time_limit, "Wall-time limit per run, seconds")
      ->capture_default_str();
  app.add_option("--scenes", scenes)->capture_default_str();
  app.add_option(
         "--strategies", strategies,
         "paper, default, direct, hybrid, direct-topology (direct with search.identify topology), "
         "default-ga (default without the direct seed)")
      ->capture_default_str();
  app.add_option("--elites", variant.elites,
                 "Override the strategies' elite count (a variant, not the strategy)");
  app.add_option(
         "--roulette-exponent", variant.roulette_exponent,
         "Override the roulette weights' exponent p, weights e^-p (a variant, not the strategy)")
      ->check(CLI::PositiveNumber);
  app.add_flag("--local-optima", local_optima,
               "After each scene, examine the best genome of every run that was not exact: single "
               "flips that "
               "improve it, else pairs of flips (all pairs; scenes of at most 100 genes)");
  app.add_option("--full-run", full_run, "Time full 1000-generation runs of this scene instead");
  app.add_option("--repeats", repeats, "Runs per strategy for --full-run")->capture_default_str();
  app.add_option(
      "--noise", noise,
      "Noisy references: Gaussian noise of this fraction of the displacement (seed s draws it)");
  CLI11_PARSE(app, argc, argv);
  if (!full_run.empty() && variant.any()) {
    std::fprintf(stderr,
                 "search_experiment: --full-run times the strategies as they are; --elites and "
                 "--roulette-exponent do not apply\n");
    return 64;
  }
  if (!full_run.empty()) {
    std::printf(
        "| scene | strategy | threads | median | max | evaluations per run | cache hits "
        "|\n|---|---|---:|---:|---:|---:|---:|\n");
    return FullRun(full_run, threads, repeats);
  }

  std::string error_table =
      "| scene | strategy | after 1 ms | 10 ms | 100 ms | 1 s | 10 s "
      "|\n|---|---|---:|---:|---:|---:|---:|\n";
  std::string optima_table =
      "| scene | strategy | not exact | a single flip improves (improving flips: median) | "
      "single-flip optima | "
      "of which a pair of flips improves |\n|---|---|---:|---:|---:|---:|\n";
  std::printf(
      "| scene | strategy | exact | generations to exact (median / p90) | evaluations to exact "
      "(median / p90) | "
      "time to exact (median / p90) | not exact: final error (median), missing + extra (median) |\n"
      "|---|---|---:|---:|---:|---:|---|\n");
  for (const std::string& scene : Split(scenes)) {
    const Scene clean = examples::Make(scene);
    const Problem truth = Problem::Build(clean);
    std::vector<std::unique_ptr<Problem>> problems;  // per seed when noisy
    if (noise > 0.0) {
      for (int s = 1; s <= seeds; ++s) {
        problems.push_back(std::make_unique<Problem>(
            examples::WithMeasurementNoise(clean, noise, static_cast<std::uint64_t>(s))));
      }
    }
    for (const std::string& strategy_name : Split(strategies)) {
      // "direct-topology": strategy direct with search.identify topology; "default-ga": the
      // default GA without its direct seed (the memetic GA alone).
      const bool topology_only = strategy_name == "direct-topology";
      const bool no_direct_seed = strategy_name == "default-ga";
      const std::string base = topology_only    ? "direct"
                               : no_direct_seed ? "default"
                                                : strategy_name;
      const std::optional<Strategy> parsed = proto::ParseStrategy(base);
      if (!parsed) {
        std::fprintf(stderr, "search_experiment: unknown strategy '%s'\n", strategy_name.c_str());
        return 64;
      }
      const Strategy strategy = *parsed;
      if (variant.roulette_exponent > 0.0 &&
          StrategyDefaults(strategy, truth.gene_count()).selection !=
              SearchOptions::Selection::kRoulette) {
        std::fprintf(stderr,
                     "search_experiment: --roulette-exponent applies to roulette selection "
                     "(paper), not to '%s'\n",
                     strategy_name.c_str());
        return 64;
      }
      std::vector<RunRecord> runs;
      for (int s = 1; s <= seeds; ++s) {
        const Problem& problem = noise > 0.0 ? *problems[static_cast<std::size_t>(s - 1)] : truth;
        runs.push_back(RunOnce(problem, truth, strategy, static_cast<std::uint64_t>(s), threads,
                               time_limit, variant, topology_only, no_direct_seed));
        std::fprintf(stderr, "%s %s seed %d: exact %d, %d generations, %.3f s, e %.3g\n",
                     scene.c_str(), strategy_name.c_str(), s, runs.back().exact,
                     runs.back().generations, runs.back().seconds, runs.back().final_error);
      }
      std::vector<double> gens, evals, secs, errors, wrong;
      int exact = 0;
      for (const RunRecord& r : runs) {
        if (r.exact) {
          ++exact;
          gens.push_back(r.generations);
          evals.push_back(static_cast<double>(r.evaluations));
          secs.push_back(r.seconds);
        } else {
          errors.push_back(r.final_error);
          wrong.push_back(r.missing + r.extra);
        }
      }
      std::printf("| %s | %s | %d / %d | %s / %s | %s / %s | %s / %s | %s |\n", scene.c_str(),
                  strategy_name.c_str(), exact, seeds, Number(Quantile(gens, 0.5), ".0f").c_str(),
                  Number(Quantile(gens, 0.9), ".0f").c_str(),
                  Number(Quantile(evals, 0.5), ".0f").c_str(),
                  Number(Quantile(evals, 0.9), ".0f").c_str(), Seconds(Quantile(secs, 0.5)).c_str(),
                  Seconds(Quantile(secs, 0.9)).c_str(),
                  errors.empty()
                      ? "—"
                      : (Number(Quantile(errors, 0.5)) + ", " + Number(Quantile(wrong, 0.5), ".1f"))
                            .c_str());
      std::fflush(stdout);
      error_table += "| " + scene + " | " + strategy_name + " |";
      for (std::size_t c = 0; c < std::size(kCheckpoints); ++c) {
        // A seed still on its first generation counts as worse than any error (+inf); the
        // lower median, so that an even count needs no average with infinity.
        std::vector<double> at;
        for (const RunRecord& r : runs)
          at.push_back(std::isnan(r.error_at[c]) ? INFINITY : r.error_at[c]);
        std::sort(at.begin(), at.end());
        const double median = at[(at.size() - 1) / 2];
        const std::string cell = std::isinf(median) ? "—" : Number(median);
        error_table += " " + cell + " |";
      }
      error_table += "\n";
      if (local_optima) {
        int failed = 0, improvable = 0, optima = 0, pair_improvable = 0, pairs_examined = 0;
        std::vector<double> flips;
        for (std::size_t i = 0; i < runs.size(); ++i) {
          if (runs[i].exact) continue;
          ++failed;
          const Problem& problem = noise > 0.0 ? *problems[i] : truth;
          const Neighbourhood n = ExamineNeighbourhood(problem, runs[i].best);
          std::fprintf(stderr, "%s %s seed %zu: %d improving flips, %d improving pairs\n",
                       scene.c_str(), strategy_name.c_str(), i + 1, n.improving_flips,
                       n.improving_pairs);
          if (n.improving_flips > 0) {
            ++improvable;
            flips.push_back(n.improving_flips);
          } else {
            ++optima;
            pairs_examined += n.improving_pairs >= 0;
            pair_improvable += n.improving_pairs > 0;
          }
        }
        optima_table +=
            "| " + scene + " | " + strategy_name + " | " + std::to_string(failed) + " | " +
            std::to_string(improvable) + " (" + Number(Quantile(flips, 0.5), ".0f") + ") | " +
            std::to_string(optima) + " | " +
            (pairs_examined == optima ? std::to_string(pair_improvable) : "not examined") + " |\n";
      }
    }
  }
  std::printf("\nMedian normalised error of the best genome found so far, against wall time:\n\n%s",
              error_table.c_str());
  if (local_optima)
    std::printf("\nThe best genomes of the runs that were not exact:\n\n%s", optima_table.c_str());
  return 0;
}

}  // namespace
}  // namespace springfit

int main(int argc, char** argv) {
  return springfit::Main(argc, argv);
}
