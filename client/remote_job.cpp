#include "client/remote_job.h"

#include <iostream>

#include "client/exit_codes.h"
#include "client/progress_line.h"
#include "proto/search_codec.h"

namespace springfit::cli {
using proto::Json;

Json JobIdParams(std::int64_t job_id) {
  Json params;
  params["job_id"] = job_id;
  return params;
}

void AddServerFlags(CLI::App* command, ServerOptions& options) {
  command->add_option(
      "--server", options.server,
      "springfitd address HOST:PORT (default: $SPRINGFIT_SERVER, else 127.0.0.1:7117)");
  command->add_option("--token-file", options.token_file,
                      "File holding the server's token (default: $SPRINGFIT_TOKEN)");
}

Json WatchJob(RpcClient& client, std::int64_t job_id, bool quiet) {
  const Json job = client.Call("job.watch", JobIdParams(job_id));
  ProgressLine progress(job.value("max_generations", 0), quiet);
  while (true) {
    const Json n = client.NextNotification();
    const Json& p = n["params"];
    if (p.value("job_id", std::int64_t{-1}) != job_id) continue;
    if (n["method"] == "job.progress") {
      Json row = p;
      row.erase("job_id");
      row.erase("max_generations");
      progress.Report(proto::TraceRowFromJson(row, "params"), false);
    } else if (n["method"] == "job.finished") {
      if (p["progress"].is_object())
        progress.Report(proto::TraceRowFromJson(p["progress"], "params.progress"), true);
      return p;
    }
  }
}

std::vector<TraceRow> FetchTrace(RpcClient& client, std::int64_t job_id) {
  std::vector<TraceRow> rows;
  Json params = JobIdParams(job_id);
  params["limit"] = 10000;
  params["after"] = -1;
  while (true) {
    const Json page = client.Call("job.trace", params);
    for (std::size_t i = 0; i < page["rows"].size(); ++i) {
      rows.push_back(proto::TraceRowFromJson(page["rows"][i], "rows[" + std::to_string(i) + "]"));
    }
    if (page["next_after"].is_null()) return rows;
    params["after"] = page["next_after"];
  }
}

int ExitCodeOfJobState(const std::string& state) {
  if (state == "succeeded") return kExitOk;
  if (state == "cancelled") return kExitCancelled;
  if (state == "failed") return kExitJobFailed;
  return kExitWrongState;
}

}  // namespace springfit::cli
