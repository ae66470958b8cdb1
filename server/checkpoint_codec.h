// The byte form of a search's state (engine/search/genetic_search.h, SearchState), as the
// store keeps it for a running job.
//
// Binary rather than JSON: a checkpoint carries the fitness cache (up to 2^18 genomes), and
// it must round-trip every double exactly so that a resumed job repeats an uninterrupted
// one bit for bit. Genomes are packed 8 genes per byte; numbers are the host's bytes, read
// back on the same host (a checkpoint is not an exchange format: a daemon moved to another
// architecture restarts interrupted jobs from generation 0, see DecodeCheckpoint).
#pragma once
#include <string>

#include "engine/search/genetic_search.h"

namespace springfit::server {

std::string EncodeCheckpoint(const SearchState& state, int genes);

// Throws std::runtime_error when the bytes are not a checkpoint of a problem with `genes`
// genes written by this version (the caller then starts the job afresh).
SearchState DecodeCheckpoint(const std::string& bytes, int genes);

}  // namespace springfit::server
