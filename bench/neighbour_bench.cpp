// Neighbour queries against scene size (bench/RESULTS.md, "Neighbour queries"): the k-d tree
// (engine/model/point_index.h) behind k-nearest candidates, the coincident-node check of validation
// and the memetic search's swap partners, each of which compared every pair before.
//
//   build/bench/neighbour_bench --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <random>

#include "engine/api/problem.h"
#include "engine/examples/catalog.h"
#include "engine/model/candidates.h"
#include "engine/model/point_index.h"
#include "engine/search/genetic_search.h"
#include "io/example_catalog.h"

namespace springfit {
namespace {

// n nodes jittered around a square grid (no exact ties), seeded.
Scene Cloud(int n) {
  Scene s;
  s.dimension = 2;
  const int side = static_cast<int>(std::ceil(std::sqrt(n)));
  s.rest.resize(2 * n);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  for (int i = 0; i < n; ++i)
    s.rest.segment(2 * i, 2) << (i % side) + jitter(rng), (i / side) + jitter(rng);
  s.candidates.kind = CandidateSpec::Kind::kNearest;
  s.candidates.k = 8;
  return s;
}

void BM_NearestCandidates(benchmark::State& state) {
  const Scene s = Cloud(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(GenerateCandidates(s));
  state.counters["nodes"] = static_cast<double>(state.range(0));
}

// Validation's coincident-node check on nodes along one vertical line, the layout that made
// the sweep along x quadratic (100k nodes took 20-40 s).
void BM_CoincidentNodesOnALine(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  Vector line(2 * n);
  for (int i = 0; i < n; ++i) line.segment(2 * i, 2) << 1.0, static_cast<double>(i);
  for (auto _ : state) {
    const PointIndex index(line, 2);
    int coincident = 0;
    for (int i = 0; i < n; ++i)
      coincident += static_cast<int>(index.WithinRadius(index.Point(i), 1e-9 * n).size()) - 1;
    benchmark::DoNotOptimize(coincident);
  }
  state.counters["nodes"] = n;
}

// Swap partners of the paper's grids, n x n (genes: every 8-neighbourhood spring).
const Problem& GridProblem(int n) {
  static std::map<int, std::unique_ptr<Problem>> cache;
  auto& slot = cache[n];
  if (!slot) {
    Scene s;
    s.dimension = 2;
    const std::vector<int> dims{n, n};
    s.rest = examples::GridNodes(dims, 1.0);
    s.candidates.kind = CandidateSpec::Kind::kGrid;
    s.reference.springs = examples::GridNeighbourSprings(dims);
    s.reference.stiffness = {1.0};
    s.load_cases = examples::Paper7LoadCases(2, s.rest, 1.0);
    examples::ScaleLoadsToStrain(s, 0.05);
    slot = std::make_unique<Problem>(std::move(s));
  }
  return *slot;
}

void BM_SwapPartners(benchmark::State& state) {
  const Problem& p = GridProblem(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(GeneticSearch::SwapPartners(p, 0.75));
  state.counters["genes"] = p.gene_count();
}

BENCHMARK(BM_NearestCandidates)->Arg(1000)->Arg(10000)->Arg(100000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CoincidentNodesOnALine)
    ->Arg(1000)
    ->Arg(10000)
    ->Arg(100000)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SwapPartners)->Arg(20)->Arg(43)->Arg(60)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace springfit

BENCHMARK_MAIN();
