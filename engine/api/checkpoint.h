// The engine's public surface (engine/api/): what a checkpoint and the stores keep of a search:
// its state (to resume from) and genomes in their packed byte form.
#pragma once

#include "engine/genome/genome_packing.h"
#include "engine/search/search_state.h"
