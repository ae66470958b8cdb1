#include "engine/search/genetic_search.h"

#include <algorithm>
#include <numeric>
#include <stdexcept>
#include <string>
#include <utility>

#include "engine/model/point_index.h"
#include "engine/runtime/wall_clock.h"
#include "engine/search/genetic_operators.h"

namespace springfit {

GeneticSearch::GeneticSearch(const Problem& problem, SearchOptions options,
                             FitnessEvaluator& evaluator)
    : problem_(&problem),
      options_(options),
      evaluator_(&evaluator),
      random_(options.seed),
      started_(std::chrono::steady_clock::now()) {
  options_.Validate();
  if (options_.local_search && options_.local_search_swaps) {
    swap_partners_ = SwapPartners(problem, options_.swap_radius);
  }
}

TraceRow GeneticSearch::Initialize() {
  const int n = options_.population;
  std::vector<Genome> seeds = std::move(state_.seeds);
  const double seeded_seconds = state_.seeded_seconds;
  state_ = SearchState{};
  state_.population.reserve(n);
  for (int i = 0; i < n; ++i) {
    Genome drawn = InitialGenome(i);  // drawn for every place, so seeding moves no other draw
    state_.population.push_back(i < static_cast<int>(seeds.size()) ? seeds[i] : std::move(drawn));
  }
  state_.seeds = std::move(seeds);
  state_.seeded_seconds = seeded_seconds;
  state_.fitness = evaluator_->Evaluate(state_.population);
  state_.best = state_.population.front();
  state_.best_fitness = state_.fitness.front();
  UpdateBest();
  if (options_.local_search && !TargetReached() && !PollInterrupt()) LocalSearch();
  return Row();
}

bool GeneticSearch::PollInterrupt() {
  if (!interrupted_ && interruption_ && interruption_->Check()) interrupted_ = true;
  return interrupted_;
}

void GeneticSearch::SeedInitialPopulation(std::vector<Genome> genomes, double elapsed_seconds) {
  const auto genes = static_cast<std::size_t>(problem_->gene_count());
  for (const Genome& g : genomes) {
    if (g.size() != genes)
      throw std::invalid_argument("GeneticSearch::SeedInitialPopulation: wrong genome size");
  }
  state_.seeds = std::move(genomes);
  state_.seeded_seconds = elapsed_seconds;
  // The earlier phases' time replaces whatever the clock counted since construction.
  elapsed_before_ = elapsed_seconds;
  started_ = std::chrono::steady_clock::now();
}

Genome GeneticSearch::InitialGenome(int i) {
  const double density = options_.initial_density_low +
                         (options_.initial_density_high - options_.initial_density_low) *
                             (i + 0.5) / options_.population;
  return RandomGenome(problem_->gene_count(), density, random_);
}

double GeneticSearch::TargetError() const {
  return std::max(options_.target_normalized_error, kExactNormalizedError);
}

void GeneticSearch::Restore(const SearchState& state) {
  const auto genes = static_cast<std::size_t>(problem_->gene_count());
  bool consistent = static_cast<int>(state.population.size()) == options_.population &&
                    state.fitness.size() == state.population.size() && state.best.size() == genes &&
                    (state.local_optimum.empty() || state.local_optimum.size() == genes);
  for (const Genome& g : state.population) consistent = consistent && g.size() == genes;
  for (const Genome& g : state.seeds) consistent = consistent && g.size() == genes;
  if (!consistent) {
    throw std::invalid_argument(
        "GeneticSearch::Restore: the state does not match this problem and options");
  }
  state_ = state;
  random_.RestoreState(state.random_state);
  evaluator_->set_counters(state.counters);
  evaluator_->cache().Clear();
  elapsed_before_ = state.elapsed_seconds;
  started_ = std::chrono::steady_clock::now();
}

TraceRow GeneticSearch::Step() {
  const Fitness before = state_.best_fitness;
  state_.population = Breed();
  state_.fitness = evaluator_->Evaluate(state_.population);
  ++state_.generation;
  UpdateBest();
  if (options_.local_search && !TargetReached() && !PollInterrupt()) LocalSearch();
  if (interrupted_) return Row();
  state_.stall =
      state_.best_fitness.normalized_error < before.normalized_error ? 0 : state_.stall + 1;
  return Row();
}

bool GeneticSearch::TargetReached() const {
  return !state_.population.empty() && state_.best_fitness.normalized_error <= TargetError();
}

SearchState GeneticSearch::Snapshot() const {
  SearchState s = state_;
  s.random_state = random_.SaveState();
  s.counters = evaluator_->counters();
  s.elapsed_seconds = ElapsedSeconds();
  return s;
}

std::vector<Genome> GeneticSearch::Breed() {
  const int n = options_.population;
  const std::vector<Fitness>& fit = state_.fitness;
  // Roulette weights or tournament errors, both unit-free.
  std::vector<double> key(n);
  for (int i = 0; i < n; ++i) {
    key[i] = options_.selection == SearchOptions::Selection::kRoulette
                 ? RouletteWeight(fit[i].normalized_error, options_.roulette_exponent)
                 : fit[i].normalized_error;
  }
  std::vector<Genome> next;
  next.reserve(n);
  if (options_.elites > 0) {
    std::vector<int> order(n);
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
      return fit[a].normalized_error < fit[b].normalized_error;
    });
    for (int e = 0; e < options_.elites; ++e) next.push_back(state_.population[order[e]]);
  }
  while (static_cast<int>(next.size()) < n) {
    Genome a = state_.population[Select(key)];
    Genome b = state_.population[Select(key)];
    if (random_.Bernoulli(options_.crossover_probability)) {
      if (options_.crossover == SearchOptions::Crossover::kOnePoint) {
        OnePointCrossover(a, b, random_);
      } else {
        UniformCrossover(a, b, random_);
      }
    }
    BitFlipMutation(a, options_.mutation_probability, random_);
    BitFlipMutation(b, options_.mutation_probability, random_);
    next.push_back(std::move(a));
    if (static_cast<int>(next.size()) < n) next.push_back(std::move(b));
  }
  return next;
}

int GeneticSearch::Select(const std::vector<double>& key) {
  return options_.selection == SearchOptions::Selection::kRoulette
             ? RouletteSelect(key, random_)
             : TournamentSelect(key, options_.tournament_size, random_);
}

void GeneticSearch::UpdateBest() {
  for (std::size_t i = 0; i < state_.population.size(); ++i) {
    if (state_.fitness[i].normalized_error < state_.best_fitness.normalized_error) {
      state_.best = state_.population[i];
      state_.best_fitness = state_.fitness[i];
      state_.best_generation = state_.generation;
    }
  }
}

namespace {

// A local-search move: flip gene `a`, and gene `b` too when b >= 0 (a swap).
struct Move {
  int a = 0;
  int b = -1;
};

}  // namespace

std::vector<std::vector<int>> GeneticSearch::SwapPartners(const Problem& problem, double radius) {
  // Springs whose midpoints lie within `radius` times the shorter rest length: the two
  // diagonals of a cell (same midpoint), a diagonal and a side of its cell. Exchanging one
  // for the other changes the model locally; a single flip cannot (removing either alone
  // often leaves a mechanism).
  const SpringGeometry& c = problem.candidates();
  const int d = problem.dimension();
  const Vector& rest = problem.scene().rest;
  const std::vector<int>& genes = problem.gene_candidates();
  const int n = static_cast<int>(genes.size());
  Vector mid(static_cast<Eigen::Index>(d) * n);
  for (int g = 0; g < n; ++g) {
    const NodePair pair = c.pairs[genes[g]];
    mid.segment(d * g, d) =
        0.5 * (rest.segment(d * pair.first, d) + rest.segment(d * pair.second, d));
  }
  // A k-d tree over the midpoints proposes, for each spring, those within radius times its
  // own length (a bound on the pair's limit); the exact test below decides. O(n log n) for
  // local meshes, where comparing every pair was O(n^2) (bench/RESULTS.md, "Neighbour queries").
  const PointIndex index(mid, d);
  std::vector<std::vector<int>> partners(n);
  for (int g = 0; g < n; ++g) {
    const double reach = radius * c.rest_length[genes[g]] * (1.0 + 1e-9);
    for (const int h : index.WithinRadius(index.Point(g), reach)) {
      if (h == g) continue;
      const double limit = radius * std::min(c.rest_length[genes[g]], c.rest_length[genes[h]]);
      if ((mid.segment(d * g, d) - mid.segment(d * h, d)).squaredNorm() <= limit * limit)
        partners[g].push_back(h);
    }
  }
  return partners;
}

namespace {

// The moves of a local-search phase, in a fresh random order so that repeated searches do not
// favour low indices: single flips, or swaps of a present spring for an absent nearby one.
std::vector<Move> ShuffledMoves(const Genome& genome, bool swaps,
                                const std::vector<std::vector<int>>& swap_partners,
                                RandomStream& random) {
  std::vector<Move> moves;
  for (int g = 0; g < static_cast<int>(genome.size()); ++g) {
    if (!swaps) {
      moves.push_back({g, -1});
      continue;
    }
    if (!genome[g]) continue;
    for (int h : swap_partners[g]) {
      if (!genome[h]) moves.push_back({g, h});
    }
  }
  for (int i = static_cast<int>(moves.size()) - 1; i > 0; --i)
    std::swap(moves[i], moves[random.Below(i + 1)]);
  return moves;
}

void Apply(const Move& m, Genome& genome) {
  genome[m.a] ^= 1;
  if (m.b >= 0) genome[m.b] ^= 1;
}

// The moves of a batch that improve on `error`, best first (ties: batch order).
std::vector<int> ImprovingMoves(const std::vector<Fitness>& results, double error) {
  std::vector<int> improving;
  for (std::size_t j = 0; j < results.size(); ++j) {
    if (results[j].normalized_error < error) improving.push_back(static_cast<int>(j));
  }
  std::stable_sort(improving.begin(), improving.end(), [&](int x, int y) {
    return results[x].normalized_error < results[y].normalized_error;
  });
  return improving;
}

// Every improving move of a batch at once, skipping any that touches a gene an earlier one
// changed: moves on distant springs act almost independently.
Genome CombinedMoves(Genome genome, const std::vector<Move>& batch,
                     const std::vector<int>& improving) {
  std::vector<std::uint8_t> touched(genome.size(), 0);
  for (int j : improving) {
    const Move& m = batch[j];
    if (touched[m.a] || (m.b >= 0 && touched[m.b])) continue;
    Apply(m, genome);
    touched[m.a] = 1;
    if (m.b >= 0) touched[m.b] = 1;
  }
  return genome;
}

}  // namespace

int GeneticSearch::LocalSearchStart() const {
  // The best new individual (the first among equals): the elites are the results of earlier
  // local searches, the children are where new optima come from.
  const int first = state_.generation == 0 ? 0 : options_.elites;
  int b = first;
  for (int i = first + 1; i < options_.population; ++i) {
    if (state_.fitness[i].normalized_error < state_.fitness[b].normalized_error) b = i;
  }
  return b;
}

bool GeneticSearch::TryCombined(Genome combined, Genome& next, Fitness& next_fitness) {
  Fitness combined_fitness = next_fitness;
  try {
    combined_fitness = evaluator_->Evaluate({combined}).front();
  } catch (const springfit::Interrupted&) {
    interrupted_ = true;  // the batch's best move stands
    return false;
  }
  if (!(combined_fitness.normalized_error < next_fitness.normalized_error)) return false;
  next = std::move(combined);
  next_fitness = combined_fitness;
  return true;
}

void GeneticSearch::LocalSearch() {
  const int b = LocalSearchStart();
  Genome genome = state_.population[b];
  Fitness fitness = state_.fitness[b];
  if (problem_->gene_count() == 0 || genome == state_.local_optimum) return;

  bool swaps = false;
  std::vector<Move> moves = ShuffledMoves(genome, swaps, swap_partners_, random_);
  std::size_t position = 0;
  std::size_t unimproved = 0;  // moves tried in a row without an improvement
  bool optimum = false;
  while (true) {
    if (unimproved >= moves.size()) {
      // A whole pass without improvement: single flips give way to swaps; after swaps too,
      // the genome is a local optimum.
      if (swaps || !options_.local_search_swaps) {
        optimum = true;
        break;
      }
      swaps = true;
      moves = ShuffledMoves(genome, swaps, swap_partners_, random_);
      position = 0;
      unimproved = 0;
      if (moves.empty()) {
        optimum = true;
        break;
      }
    }
    if (PollInterrupt()) break;  // mid-search: not a local optimum
    const std::size_t size = std::min<std::size_t>(options_.local_search_batch, moves.size());
    std::vector<Move> batch;
    std::vector<Genome> neighbours(size, genome);
    for (std::size_t j = 0; j < size; ++j) {
      batch.push_back(moves[(position + j) % moves.size()]);
      Apply(batch.back(), neighbours[j]);
    }
    position = (position + size) % moves.size();
    std::vector<Fitness> results;
    try {
      results = evaluator_->Evaluate(neighbours);
    } catch (const springfit::Interrupted&) {
      interrupted_ = true;  // keep the genome reached so far
      break;
    }
    const std::vector<int> improving = ImprovingMoves(results, fitness.normalized_error);
    if (improving.empty()) {
      unimproved += size;
      continue;
    }
    Genome next = neighbours[improving.front()];
    Fitness next_fitness = results[improving.front()];
    if (options_.local_search_combine && improving.size() > 1)
      TryCombined(CombinedMoves(genome, batch, improving), next, next_fitness);
    genome = std::move(next);
    fitness = next_fitness;
    if (interrupted_ || fitness.normalized_error <= TargetError()) break;
    // After any improvement, single flips again (a swap's moves also depend on the genome).
    if (swaps) {
      swaps = false;
      moves = ShuffledMoves(genome, swaps, swap_partners_, random_);
      position = 0;
    }
    unimproved = 0;
  }
  if (optimum) state_.local_optimum = genome;
  state_.population[b] = std::move(genome);
  state_.fitness[b] = fitness;
  UpdateBest();
}

TraceRow GeneticSearch::Row() const {
  TraceRow row;
  row.generation = state_.generation;
  row.wall_seconds = ElapsedSeconds();
  row.evaluations = evaluator_->counters().evaluations;
  row.cache_hits = evaluator_->counters().cache_hits;
  row.best_cost = state_.best_fitness.cost;
  row.best_normalized_error = state_.best_fitness.normalized_error;
  double sum = 0.0;
  for (const Fitness& f : state_.fitness) sum += f.cost;
  row.mean_cost = sum / static_cast<double>(state_.fitness.size());
  if (const auto diff = problem_->CompareWithReference(state_.best)) {
    row.missing = static_cast<int>(diff->missing.size());
    row.extra = static_cast<int>(diff->extra.size());
  }
  return row;
}

double GeneticSearch::ElapsedSeconds() const {
  return elapsed_before_ + SecondsSince(started_);
}

}  // namespace springfit
