// Strategy `direct` as a run: the identification (direct_identification.h) in the shape of
// every other strategy's result (SearchResult: one trace row, generation 0), plus what only
// it has (per-spring stiffness, the force residual).
#pragma once
#include "engine/direct/direct_identification.h"
#include "engine/search/run_search.h"

namespace springfit {

struct DirectRun {
  SearchResult search;  // stop: kTargetReached when the cost reaches the target, else kCompleted
  DirectResult direct;
};

// `options.identify` decides whether the stiffness is known (DirectOptions::known_stiffness,
// the training stiffness) or identified per spring.
DirectRun RunDirect(const Problem& problem, const SearchOptions& options, const DirectOptions& direct = {});

}  // namespace springfit
