// The engine's public surface (engine/api/): running an identification: the one entry point
// RunIdentification with its run context (progress, stops, resume), the search options and
// their resolution, the strategies' names, the worker pool every run shares, interruptions, the
// wall clock of progress and timings.
#pragma once

#include "engine/identification/identify.h"
#include "engine/identification/run_bounds.h"
#include "engine/runtime/interruption.h"
#include "engine/runtime/wall_clock.h"
#include "engine/runtime/worker_pool.h"
#include "engine/search/search_options.h"
