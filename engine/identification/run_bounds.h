// What a run asks for, checked against what it can have, before any of its work: a request that
// cannot be met is refused with the number that refuses it (docs/ARCHITECTURE.md, "Bounds before
// work"), not discovered minutes or gigabytes later.
#pragma once

#include "engine/api/identify.h"
#include "engine/api/problem.h"
#include "engine/api/search_options.h"

namespace springfit {

// The probes a probe fit (or a probe certificate) of this run generates, 0 when none runs: the
// explicit search.probes, or the automatic bank's size (per support 24 point loads, 12 patches
// and d + 2 body forces; on the user's supports and the drawn ones).
long long PlannedProbes(const Problem& problem, const SearchOptions& options);

// The bytes a probe fit of this run holds at least: per probe its force and the reference's
// displacement (the bank), and the fitted model's displacement and its adjoint (the fit), each
// flat d*n doubles.
double ProbeFitBytes(const Problem& problem, const SearchOptions& options);

// The machine's physical memory in bytes (0 when it cannot be read).
double PhysicalMemoryBytes();

// CheckRunBounds, which a service calls at the door, is on the surface (engine/api/identify.h).

}  // namespace springfit
