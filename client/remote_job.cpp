#include "client/remote_job.h"

#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <iostream>

#include <fmt/format.h>

#include "client/exit_codes.h"
#include "client/progress_line.h"
#include "proto/outcome_codec.h"
#include "proto/rpc.h"
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
  command
      ->add_option("--timeout", options.timeout_seconds,
                   "Seconds to connect and to wait for each answer of the server (not for a "
                   "watched job's progress)")
      ->check(CLI::Range(0.001, 86400.0))
      ->capture_default_str();
}

namespace {

// What Ctrl-C (or SIGTERM) on a watch says before the client exits 130: the job is the
// daemon's, and it goes on. Prepared before the handler is installed: a handler may only
// write(2) and _exit(2).
char g_detach_message[256];
std::size_t g_detach_length = 0;

extern "C" void OnDetach(int) {
  [[maybe_unused]] const auto written = ::write(2, g_detach_message, g_detach_length);
  ::_exit(kExitInterrupted);
}

// Installs OnDetach for the life of a watch and restores the previous handlers after it.
class DetachOnInterrupt {
 public:
  explicit DetachOnInterrupt(std::int64_t job_id) {
    // (Into the fixed buffer, cut to its size: the handler reads no heap.)
    const auto end = fmt::format_to_n(g_detach_message, sizeof g_detach_message,
                                      "\nspringfit: stopped watching; job {0} keeps running on "
                                      "the server (springfit cancel {0} stops it, springfit "
                                      "watch {0} watches it again)\n",
                                      job_id);
    g_detach_length = std::min<std::size_t>(end.size, sizeof g_detach_message);
    previous_int_ = std::signal(SIGINT, OnDetach);
    previous_term_ = std::signal(SIGTERM, OnDetach);
  }
  ~DetachOnInterrupt() {
    std::signal(SIGINT, previous_int_);
    std::signal(SIGTERM, previous_term_);
  }
  DetachOnInterrupt(const DetachOnInterrupt&) = delete;
  DetachOnInterrupt& operator=(const DetachOnInterrupt&) = delete;

 private:
  void (*previous_int_)(int) = SIG_DFL;
  void (*previous_term_)(int) = SIG_DFL;
};

}  // namespace

Json WatchJob(RpcClient& client, std::int64_t job_id, bool quiet) {
  const DetachOnInterrupt detach(job_id);
  const Json job = client.Call("job.watch", JobIdParams(job_id));
  // A continuous job's rows are steps of its fit, not generations (the job's strategy is the
  // one that runs, `default` resolved when it was prepared).
  ProgressLine progress(job.value("max_generations", 0), quiet,
                        proto::ProgressCountsSteps(job.value("strategy", std::string())));
  while (true) {
    const Json n = client.NextNotification();
    const Json& p = n["params"];
    if (p.value("job_id", std::int64_t{-1}) != job_id) continue;
    if (n["method"] == "job.progress") {
      progress.Report(proto::TraceRowFromJson(p, "params"), false);
    } else if (n["method"] == "job.phase") {
      // Inside a step (a fit's steps, the sparsity path, the certificate), as `run` shows it.
      proto::PhaseBeat beat;
      proto::ProgressBeatFromJson(p, "params", beat);
      progress.Beat(beat.beat);
    } else if (n["method"] == "job.finished") {
      if (p["progress"].is_object())
        progress.Report(proto::TraceRowFromJson(p["progress"], "params.progress"), true);
      return p;
    } else if (n["method"] == "job.gone") {
      throw RemoteError(proto::rpc::kNoSuchJob, p.value("message", std::string("gone")), Json());
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

int ExitCodeOfJob(const proto::Json& job) {
  const std::string state = job.value("state", std::string("succeeded"));
  if (state == "cancelled") return kExitCancelled;
  if (state == "failed") return kExitJobFailed;
  if (state != "succeeded") return kExitWrongState;
  // (An older daemon's job has no outcome: its state alone.)
  if (!job.contains("outcome") || !job["outcome"].is_object()) return kExitOk;
  return ExitCodeOfVerdict(proto::OutcomeFromJson(job["outcome"], "outcome").verdict);
}

}  // namespace springfit::cli
