// The identification strategies behind one small interface, and the one place that maps a
// Strategy to its code.
//
//   paper    GeneticStrategy: the paper's GA (search_options.h)
//   direct   DirectStrategy: non-negative least squares on the force balance (engine/direct/)
//   hybrid   HybridStrategy: direct's topology seeds the memetic GA, on one clock
//   default  HybridStrategy today (bench/RESULTS.md: the fastest measured)
#pragma once

#include <memory>

#include "engine/identification/identify.h"
#include "engine/identification/run_monitor.h"

namespace springfit {

class IdentificationStrategy {
 public:
  virtual ~IdentificationStrategy() = default;
  // Runs on a prepared problem. Fills the strategy's part of the result: stop, best, trace,
  // evaluation, counters, generations, wall time, stiffness when it identifies it, and its
  // own details; RunIdentification() fills the rest. Reports beats and checks for a stop
  // through `monitor`; throws Interrupted when stopped before it had any model to return.
  virtual IdentificationResult Run(const Problem& problem, const SearchOptions& options,
                                   const RunContext& context, RunMonitor& monitor) const = 0;
};

// The genetic algorithm as the options configure it (paper, or the memetic GA alone).
class GeneticStrategy : public IdentificationStrategy {
 public:
  IdentificationResult Run(const Problem& problem, const SearchOptions& options,
                           const RunContext& context, RunMonitor& monitor) const override;
};

class DirectStrategy : public IdentificationStrategy {
 public:
  IdentificationResult Run(const Problem& problem, const SearchOptions& options,
                           const RunContext& context, RunMonitor& monitor) const override;
};

// Direct (topology only, at the training stiffness), then the GA seeded with its topology,
// the direct phase's time starting the GA's clock. A resumed run skips the direct phase.
class HybridStrategy : public IdentificationStrategy {
 public:
  IdentificationResult Run(const Problem& problem, const SearchOptions& options,
                           const RunContext& context, RunMonitor& monitor) const override;
};

std::unique_ptr<IdentificationStrategy> MakeStrategy(Strategy strategy);

}  // namespace springfit
