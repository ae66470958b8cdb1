// The byte form of a search's state (engine/search/genetic_search.h, SearchState), as the
// store keeps it for a running job.
//
// Binary rather than JSON: it must round-trip every double exactly so that a resumed job
// repeats an uninterrupted one bit for bit. It does not carry the fitness cache (format 2 did:
// up to 23 MB every 10 s, bench/RESULTS.md), which changes no result, only how many
// evaluations a resumed job answers from it. Genomes are packed 8 genes per byte; numbers are the
// host's bytes, read back on the same host (a checkpoint is not an exchange format: a daemon moved
// to another architecture restarts interrupted jobs from generation 0, see DecodeCheckpoint).
//
// A header says what wrote it: the format version, the daemon's version (version.h) and a
// fingerprint of the resolved search options (OptionsFingerprint). A checkpoint whose header
// does not match the running daemon and job is refused with a message saying which part
// differs, and the job starts again from generation 0: after an upgrade that changed an
// operator or a default, continuing would silently mix two searches.
#pragma once
#include <cstdint>
#include <string>

#include "engine/api/checkpoint.h"
#include "engine/api/identify.h"

namespace springfit::server {

// FNV-1a (64 bits) of the resolved options' JSON (proto/search_codec.h, SearchOptionsToJson).
std::uint64_t OptionsFingerprint(const SearchOptions& options);

std::string EncodeCheckpoint(const SearchState& state, int genes, std::uint64_t fingerprint);

// Throws std::runtime_error when the bytes are not a checkpoint of a problem with `genes`
// genes written by this version of the daemon for options of this fingerprint (the caller
// then starts the job afresh); the message says what differs.
SearchState DecodeCheckpoint(const std::string& bytes, int genes, std::uint64_t fingerprint);

}  // namespace springfit::server
