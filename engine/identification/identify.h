// What the engine's rooms add to its entry point (engine/api/identify.h): a run with a strategy
// chosen by the caller, for experiments and benchmarks that run one part of a composed strategy
// alone.
#pragma once

#include "engine/api/identify.h"

namespace springfit {

class IdentificationStrategy;  // engine/identification/strategy.h

// The same with a strategy chosen by the caller instead of by options.strategy (experiments
// that run one part of a composed strategy alone).
IdentificationResult RunIdentification(const Problem& problem, const SearchOptions& options,
                                       const RunContext& context,
                                       const IdentificationStrategy& strategy);

}  // namespace springfit
