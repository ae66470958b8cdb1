// The engine's public surface (engine/api/): what an identification returns: the one result
// type, its verdict (outcome and headline), the trace rows of its progress, and the
// equilibrium solver's terminations a result names.
#pragma once

#include "engine/identification/identification_result.h"
#include "engine/identification/verdict.h"
#include "engine/model/equilibrium.h"
#include "engine/runtime/trace.h"
