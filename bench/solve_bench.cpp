// Equilibrium solves and cost evaluations against scene size (bench/RESULTS.md).
//
//   build/bench/solve_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//
// Grids: 2D n x n with n = 5..80 and 3D n^3 with n = 4, 8, 12, reference = every grid-
// neighbour spring, paper7 loads scaled to 5% strain (5x5: the paper's 0.05 k h). Each solve
// starts from rest; counters report Newton iterations and projected steps per solve.
#include <benchmark/benchmark.h>

#include <map>
#include <memory>

#include "engine/api/problem.h"
#include "engine/examples/catalog.h"
#include "engine/model/equilibrium.h"
#include "engine/problem/cost.h"
#include "io/example_catalog.h"

namespace springfit {
namespace {

Scene Grid(int dimension, int n) {
  if (dimension == 2 && n == 5) return examples::Make("paper-iso-5x5");
  Scene s;
  s.dimension = dimension;
  const std::vector<int> dims(dimension, n);
  s.rest = examples::GridNodes(dims, 1.0);
  s.candidates.kind = CandidateSpec::Kind::kGrid;
  s.reference.springs = examples::GridNeighbourSprings(dims);
  s.reference.stiffness = {1.0};
  s.load_cases = examples::Paper7LoadCases(dimension, s.rest, 1.0);
  examples::ScaleLoadsToStrain(s, 0.05);
  return s;
}

// Problems are expensive to build for large grids: build each once.
const Problem& CachedProblem(int dimension, int n) {
  static std::map<std::pair<int, int>, std::unique_ptr<Problem>> cache;
  auto& slot = cache[{dimension, n}];
  if (!slot) slot = std::make_unique<Problem>(Grid(dimension, n));
  return *slot;
}

// Load case index per load type: stretch, compression, shear (paper7 order).
constexpr int kLoadCase[] = {0, 1, 2};
constexpr const char* kLoadName[] = {"stretch", "compression", "shear"};

void BM_Solve(benchmark::State& state) {
  const int dimension = static_cast<int>(state.range(0));
  const int n = static_cast<int>(state.range(1));
  const int load = static_cast<int>(state.range(2));
  const Problem& p = CachedProblem(dimension, n);
  const PreparedLoadCase& lc = p.load_cases()[kLoadCase[load]];
  const ActiveSprings springs = p.SpringsFromMask(*p.reference_mask());
  EquilibriumSolver solver(p.candidates(), p.free_sets()[lc.free_set], p.solver_options());
  Vector u;
  EquilibriumSummary summary;
  for (auto _ : state) {
    u.setZero(lc.force.size());
    summary = solver.Solve(springs, lc.force, lc.prescribed, u);
    benchmark::DoNotOptimize(u.data());
  }
  if (!summary.converged()) state.SkipWithError("did not converge");
  state.counters["iterations"] = summary.iterations;
  state.counters["projected"] = summary.projected_steps;
  state.counters["dofs"] = static_cast<double>(dimension * p.free_sets()[lc.free_set].count);
  state.SetLabel(kLoadName[load]);
}

// A full cost evaluation (every load case) of the reference topology (warm start = the
// reference's equilibrium), and of topologies with 5% of the genes flipped.
void BM_CostReference(benchmark::State& state) {
  const Problem& p =
      CachedProblem(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  CostFunction cost(p);
  const Genome genome = p.GenomeFromMask(*p.reference_mask());
  for (auto _ : state) benchmark::DoNotOptimize(cost.EvaluateGenome(genome).cost);
}

void BM_CostFlipped5Percent(benchmark::State& state) {
  const Problem& p =
      CachedProblem(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  CostFunction cost(p);
  // 16 fixed genomes, each the reference with 5% of its genes flipped (deterministic picks).
  std::vector<Genome> genomes;
  std::uint64_t x = 12345;
  for (int g = 0; g < 16; ++g) {
    Genome genome = p.GenomeFromMask(*p.reference_mask());
    const int flips = std::max(1, p.gene_count() / 20);
    for (int f = 0; f < flips; ++f) {
      x = x * 6364136223846793005ULL + 1442695040888963407ULL;
      genome[(x >> 33) % genome.size()] ^= 1;
    }
    genomes.push_back(std::move(genome));
  }
  int mechanisms = 0;
  for (const Genome& g : genomes) mechanisms += cost.EvaluateGenome(g).mechanism;
  std::size_t i = 0;
  for (auto _ : state)
    benchmark::DoNotOptimize(cost.EvaluateGenome(genomes[i++ % genomes.size()]).cost);
  state.counters["mechanisms_of_16"] = mechanisms;
}

void SolveSizes(benchmark::internal::Benchmark* b) {
  for (int load = 0; load < 3; ++load) {
    for (int n : {5, 10, 20, 40, 80}) b->Args({2, n, load});
    for (int n : {4, 8, 12}) b->Args({3, n, load});
  }
}

void CostSizes(benchmark::internal::Benchmark* b) {
  for (int n : {5, 10, 20, 40}) b->Args({2, n});
  for (int n : {4, 8}) b->Args({3, n});
}

BENCHMARK(BM_Solve)
    ->Apply(SolveSizes)
    ->ArgNames({"dim", "n", "load"})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_CostReference)
    ->Apply(CostSizes)
    ->ArgNames({"dim", "n"})
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_CostFlipped5Percent)
    ->Apply(CostSizes)
    ->ArgNames({"dim", "n"})
    ->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace springfit

BENCHMARK_MAIN();
