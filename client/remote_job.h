// What the commands that talk to springfitd share: the server flags, watching a job to its
// end, fetching a whole trace, and the exit code of a finished job's state.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "client/rpc_client.h"
#include "engine/api/checkpoint.h"
#include "engine/api/identify.h"

namespace springfit::cli {

// {"job_id": id}: the params of every method that names one job.
proto::Json JobIdParams(std::int64_t job_id);

// --server HOST:PORT and --token-file FILE (README.md, "The daemon").
void AddServerFlags(CLI::App* command, ServerOptions& options);

// Follows a job through job.watch until job.finished; draws the progress line unless quiet.
// Returns the finished job (proto/RPC.md, "Job").
proto::Json WatchJob(RpcClient& client, std::int64_t job_id, bool quiet);

// Every stored trace row of a job, following job.trace's pages.
std::vector<TraceRow> FetchTrace(RpcClient& client, std::int64_t job_id);

// The exit code of a finished job or of its result (both carry `state` and `outcome`):
// cancelled kExitCancelled, failed kExitJobFailed, succeeded its verdict's (ExitCodeOfVerdict).
int ExitCodeOfJob(const proto::Json& job);

}  // namespace springfit::cli
