#include "engine/identification/run_bounds.h"

#include <unistd.h>

#include <algorithm>

#include <fmt/format.h>

#include "engine/identification/strategy.h"
#include "engine/probe_fit/probe_bank.h"
#include "engine/runtime/input_error.h"

namespace springfit {
namespace {

// The bank's vectors per probe and the fit's (ProbeFitBytes).
constexpr double kFitVectorsPerProbe = 2.0;

bool RunsProbes(const Problem& problem, const SearchOptions& options) {
  return options.probes != 0 && problem.scene().reference.kind != Reference::Kind::kPositions &&
         ResolvedStrategy(options.strategy, problem.scene()) == Strategy::kContinuous;
}

int UserSupports(const Problem& problem) {
  return static_cast<int>(problem.free_sets().size());
}

}  // namespace

long long PlannedProbes(const Problem& problem, const SearchOptions& options) {
  if (!RunsProbes(problem, options)) return 0;
  const response::ProbeOptions defaults;
  const long long tools = problem.scene().reference.kind == Reference::Kind::kFem
                              ? response::MaximumToolCount(UserSupports(problem), defaults)
                              : 0;
  if (options.probes > 0) return options.probes + tools;
  const long long supports = UserSupports(problem) + defaults.extra_supports;
  return supports * (24 + 12 + problem.dimension() + 2) + tools;
}

double ProbeFitBytes(const Problem& problem, const SearchOptions& options) {
  const long long probes = PlannedProbes(problem, options);
  const double bank =
      response::ProbeBankBytes(probes, problem.scene().node_count(), problem.dimension());
  return bank * (1.0 + kFitVectorsPerProbe / 2.0);
}

double PhysicalMemoryBytes() {
  const long pages = sysconf(_SC_PHYS_PAGES);
  const long page = sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page > 0 ? static_cast<double>(pages) * static_cast<double>(page) : 0.0;
}

void CheckRunBounds(const Problem& problem, const SearchOptions& options, double available_bytes) {
  if (!RunsProbes(problem, options)) return;
  const response::ProbeOptions defaults;
  const int minimum = response::MinimumProbeCount(UserSupports(problem), defaults);
  if (options.probes > 0 && options.probes < minimum) {
    throw InputError(
        "search.probes",
        fmt::format("{} probes are too few: the bank has {} supports ({} of the load cases, {} "
                    "drawn from the boundary) and three families, and each (support, family) "
                    "group needs a fitted, a choosing and a held-out probe: at least {}, or "
                    "\"auto\"",
                    options.probes, UserSupports(problem) + defaults.extra_supports,
                    UserSupports(problem), defaults.extra_supports, minimum));
  }
  if (available_bytes <= 0.0) available_bytes = 0.5 * PhysicalMemoryBytes();
  const double needed = ProbeFitBytes(problem, options);
  if (available_bytes > 0.0 && needed > available_bytes) {
    throw InputError(
        "search.probes",
        fmt::format("{} probes on {} nodes need at least {:.1f} GB for the probe fit (the bank "
                    "and the fit's responses, {} doubles per probe), above the {:.1f} GB this "
                    "machine allows a run (half its memory): ask for fewer probes",
                    PlannedProbes(problem, options), problem.scene().node_count(), needed / 1e9,
                    static_cast<long long>(
                        needed / static_cast<double>(PlannedProbes(problem, options)) / 8.0),
                    available_bytes / 1e9));
  }
}

}  // namespace springfit
