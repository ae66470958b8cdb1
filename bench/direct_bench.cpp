// Strategy `direct` on the MSS-reference examples and on thinned grids of growing size:
// exact topology recovery, stiffness error, time per phase (bench/RESULTS.md, "Direct").
//
//   build/bench/direct_bench                  # examples, then the size table
//   build/bench/direct_bench --sizes 5,10,20  # 2D n x n and 3D grids of these sizes
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "engine/api/problem.h"
#include "engine/direct/direct_identification.h"
#include "engine/examples/catalog.h"
#include "engine/identification/identify.h"
#include "io/example_catalog.h"

using namespace springfit;

namespace {

struct Row {
  std::string scene;
  int nodes = 0;
  int genes = 0;
  bool exact = false;
  int missing = 0, extra = 0;
  double stiffness_error = 0.0;  // max over reference springs of |w - k| / k
  double normalized_error = 0.0;
  double assemble = 0.0, solve = 0.0, evaluate = 0.0, build = 0.0;
  int iterations = 0;
  double smallest_true = 0.0, largest_absent = 0.0;
};

Row Measure(Scene scene, int repeats) {
  Row row;
  row.scene = scene.name;
  const auto t0 = std::chrono::steady_clock::now();
  const Problem problem = Problem::Build(std::move(scene));
  row.build = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  row.nodes = problem.scene().node_count();
  row.genes = problem.gene_count();
  DirectResult best;
  for (int r = 0; r < repeats; ++r) {
    DirectResult d = IdentifyDirect(problem);
    if (r == 0 || d.assemble_seconds + d.solve_seconds < best.assemble_seconds + best.solve_seconds)
      best = std::move(d);
  }
  const auto difference = problem.CompareWithReference(best.genome);
  row.missing = difference ? static_cast<int>(difference->missing.size()) : -1;
  row.extra = difference ? static_cast<int>(difference->extra.size()) : -1;
  row.exact = difference && difference->hamming() == 0;
  const std::vector<double> truth = problem.ReferenceWeights();
  for (std::size_t g = 0; g < truth.size(); ++g) {
    if (truth[g] > 0.0)
      row.stiffness_error =
          std::max(row.stiffness_error, std::abs(best.weights[g] - truth[g]) / truth[g]);
  }
  // Diagnostic: the smallest true weight and the largest weight of an absent spring, relative
  // to the largest weight: the room the topology threshold has.
  if (const auto& mask = problem.reference_genome()) {
    double lo = 1e300, hi = 0.0, top = 0.0;
    for (double w : best.weights) top = std::max(top, w);
    for (std::size_t g = 0; g < best.weights.size(); ++g) {
      if ((*mask)[g])
        lo = std::min(lo, best.weights[g] / top);
      else
        hi = std::max(hi, best.weights[g] / top);
    }
    row.smallest_true = lo;
    row.largest_absent = hi;
  }
  row.normalized_error = best.evaluation.normalized_error;
  row.assemble = best.assemble_seconds;
  row.solve = best.solve_seconds;
  row.evaluate = best.evaluate_seconds;
  row.iterations = best.nnls.iterations;
  return row;
}

void Print(const Row& r) {
  std::printf("| %s | %d | %d | %s | %d / %d | %.1e | %.1e | %.2f | %.2f | %.2f | %d | %.2f |\n",
              r.scene.c_str(), r.nodes, r.genes, r.exact ? "yes" : "no", r.missing, r.extra,
              r.stiffness_error, r.normalized_error, 1e3 * r.assemble, 1e3 * r.solve,
              1e3 * (r.assemble + r.solve), r.iterations, r.evaluate);
  std::fprintf(stderr, "%s: smallest true weight %.2e, largest absent %.2e (of the largest)\n",
               r.scene.c_str(), r.smallest_true, r.largest_absent);
  std::fflush(stdout);
}

// Noise: `draws` noisy copies of an MSS example; how often direct finds the true topology.
void MeasureNoise(const std::string& name, double fraction, int draws, Identify identify,
                  int hybrid_generations) {
  const Scene clean = examples::Make(name);
  const Problem truth = Problem::Build(clean);
  int exact = 0;
  double seconds = 0.0;
  std::vector<int> wrong;
  double worst_error = 0.0;
  for (int draw = 1; draw <= draws; ++draw) {
    const Problem noisy = Problem::Build(
        examples::WithMeasurementNoise(clean, fraction, static_cast<std::uint64_t>(draw)));
    Genome genome;
    double error = 0.0;
    if (hybrid_generations > 0) {
      Scene scene = noisy.scene();
      scene.search.strategy = Strategy::kHybrid;
      scene.search.max_generations = hybrid_generations;
      const Problem hybrid = Problem::Build(std::move(scene));
      RunContext run;
      run.threads = 2;
      const IdentificationResult result = RunIdentification(
          hybrid, ResolveSearchOptions(hybrid.scene().search, hybrid.gene_count()), run);
      genome = result.best;
      error = result.evaluation.normalized_error;
      seconds += result.wall_seconds;
    } else {
      DirectOptions o;
      if (identify == Identify::kTopology) o.known_stiffness = noisy.training_stiffness();
      const DirectResult r = IdentifyDirect(noisy, o);
      genome = r.genome;
      error = r.evaluation.normalized_error;
      seconds += r.assemble_seconds + r.solve_seconds + r.evaluate_seconds;
    }
    const auto difference = truth.CompareWithReference(genome);
    exact += difference->hamming() == 0;
    wrong.push_back(difference->hamming());
    worst_error = std::max(worst_error, error);
  }
  std::sort(wrong.begin(), wrong.end());
  const int median = wrong.empty() ? 0 : wrong[wrong.size() / 2];
  const int worst = wrong.empty() ? 0 : wrong.back();
  std::printf("| %s | %g | %s | %d / %d | %d | %d | %.2g | %.3f |\n", name.c_str(), fraction,
              hybrid_generations > 0
                  ? ("hybrid, " + std::to_string(hybrid_generations) + " generations").c_str()
              : identify == Identify::kTopology ? "direct, topology"
                                                : "direct, topology and stiffness",
              exact, draws, median, worst, worst_error, seconds / draws);
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"direct_bench: strategy direct, exactness, stiffness error and time"};
  std::vector<int> sizes2{5, 10, 20, 40, 70, 100};
  std::vector<int> sizes3{4, 6, 8, 10, 12};
  int repeats = 5;
  bool examples_only = false;
  std::vector<double> noise;
  int draws = 20;
  int hybrid_generations = 0;
  std::vector<std::string> noise_scenes{"paper-iso-5x5", "paper-aniso-5x5"};
  app.add_option("--sizes2", sizes2, "2D grid sizes n (n x n nodes)")->delimiter(',');
  app.add_option("--sizes3", sizes3, "3D grid sizes n (n^3 nodes)")->delimiter(',');
  app.add_option("--repeats", repeats, "Runs per scene; the fastest is reported")
      ->check(CLI::PositiveNumber);
  app.add_flag("--examples-only", examples_only, "Only the example scenes");
  app.add_option("--noise", noise, "Only the noise table, at these fractions (e.g. 0.001,0.01)")
      ->delimiter(',');
  app.add_option("--hybrid", hybrid_generations,
                 "Also strategy hybrid with this many GA generations (noise table)");
  app.add_option("--noise-scenes", noise_scenes, "Scenes of the noise table")->delimiter(',');
  app.add_option("--draws", draws, "Noise draws per scene and fraction")
      ->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);

  if (!noise.empty()) {
    std::printf(
        "| scene | noise | strategy | exact topology | median wrong springs | worst | worst "
        "normalized error | "
        "mean s |\n|---|---|---|---|---|---|---|---|\n");
    for (const double f : noise) {
      for (const std::string& name : noise_scenes) {
        MeasureNoise(name, f, draws, Identify::kTopology, 0);
        MeasureNoise(name, f, draws, Identify::kTopologyAndStiffness, 0);
        if (hybrid_generations > 0)
          MeasureNoise(name, f, draws, Identify::kTopology, hybrid_generations);
      }
    }
    return 0;
  }

  std::printf(
      "| scene | nodes | genes | exact | missing / extra | stiffness rel. error | normalized error "
      "| "
      "assemble ms | NNLS ms | direct ms | pivots | evaluate s "
      "|\n|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const char* name :
       {"paper-iso-5x5", "paper-aniso-5x5", "kidney-2d", "grid3d-4x4x4", "stiff-2d"}) {
    Print(Measure(examples::Make(name), repeats));
  }
  if (examples_only) return 0;
  // Growth: the least-squares slope of log(direct time) against log(genes), over scenes of at
  // least 1000 genes (below that, fixed costs dominate).
  auto exponent = [](const std::vector<Row>& rows) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    int m = 0;
    for (const Row& r : rows) {
      if (r.genes < 1000) continue;
      const double x = std::log(r.genes), y = std::log(r.assemble + r.solve);
      sx += x, sy += y, sxx += x * x, sxy += x * y, ++m;
    }
    return m < 2 ? std::nan("") : (m * sxy - sx * sy) / (m * sxx - sx * sx);
  };
  std::vector<Row> rows2, rows3;
  for (const int n : sizes2) {
    rows2.push_back(Measure(examples::ThinnedGrid({n, n}, 1, 2.0), n >= 40 ? 1 : repeats));
    Print(rows2.back());
  }
  for (const int n : sizes3) {
    rows3.push_back(Measure(examples::ThinnedGrid({n, n, n}, 1, 2.0), n >= 8 ? 1 : repeats));
    Print(rows3.back());
  }
  std::printf(
      "\ngrowth exponent of direct time in genes (scenes of >= 1000 genes): 2D %.2f, 3D %.2f\n",
      exponent(rows2), exponent(rows3));
  return 0;
}
