// springfit status | watch | result | trace | cancel | delete | list | info: reading and
// managing springfitd's jobs (README.md, "The daemon"; proto/RPC.md).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <iostream>
#include <optional>

#include <fmt/format.h>

#include "client/commands.h"
#include "client/error_reporting.h"
#include "client/exit_codes.h"
#include "client/remote_job.h"
#include "client/result_summary.h"
#include "proto/job.h"
#include "proto/search_codec.h"

namespace springfit::cli {
namespace {
using proto::Json;

std::vector<std::string> StateNames() {
  std::vector<std::string> names;
  for (const proto::JobState s : proto::AllJobStates()) names.emplace_back(proto::JobStateName(s));
  return names;
}

struct JobArgs {
  ServerOptions server;
  std::int64_t job_id = 0;
  bool json = false;
  bool csv = false;
  bool quiet = false;
  std::string output_path;
  std::optional<std::string> state;
  std::optional<std::string> label;
  int limit = 100;
  std::optional<std::int64_t> cursor;
  bool oldest_first = false;
};

std::string LocalTime(double unix_seconds) {
  if (unix_seconds <= 0.0) return "-";
  const auto t = static_cast<std::time_t>(unix_seconds);
  std::tm tm{};
  localtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%d %H:%M:%S", &tm);
  return text;
}

std::string ErrorText(double e) {
  return fmt::format("{:.3g}", e);
}

// Where an unfinished job has got to: a genetic search's generation of its limit; strategy
// continuous (its progress rows count steps, not generations) its step.
std::string ProgressText(const proto::JobRecord& j) {
  if (!j.progress) return "-";
  if (proto::ProgressCountsSteps(j.strategy))
    return "step " + std::to_string(j.progress->generation);
  return "gen " + std::to_string(j.progress->generation) + "/" + std::to_string(j.max_generations);
}

void PrintJob(const proto::JobRecord& j) {
  std::cout << "job:               " << j.id << (j.label.empty() ? "" : " (" + j.label + ")")
            << "\n"
            << "state:             " << proto::JobStateName(j.state) << "\n";
  if (!j.error.empty()) std::cout << "error:             " << j.error << "\n";
  std::cout << "scene:             " << j.scene_name << " (" << j.genes << " genes)\n"
            << "strategy:          " << j.strategy << " (seed " << j.seed << ", priority "
            << j.priority << ")\n"
            << "created:           " << LocalTime(j.created_at) << "\n"
            << "started:           " << LocalTime(j.started_at) << "\n"
            << "finished:          " << LocalTime(j.finished_at) << "\n";
  if (j.outcome) {
    PrintOutcome(*j.outcome, std::cout);  // in the words of `springfit run`
  } else if (j.progress) {
    const TraceRow& p = *j.progress;
    std::cout << "progress:          " << ProgressText(j) << "\n"
              << "E so far:          " << ErrorText(std::sqrt(p.best_normalized_error)) << "\n"
              << "evaluations:       " << p.evaluations << "\n";
    if (p.missing >= 0)
      std::cout << "against reference: " << p.missing << " missing, " << p.extra << " extra\n";
  }
  if (j.checkpoint_generation >= 0 && !proto::IsFinal(j.state)) {
    std::cout << "checkpoint:        generation " << j.checkpoint_generation << "\n";
  }
  if (j.exact) std::cout << "exact:             " << (*j.exact ? "yes" : "no") << "\n";
}

int Status(const JobArgs& a) {
  RpcClient client(a.server);
  const Json job = client.Call("job.get", JobIdParams(a.job_id));
  if (a.json) {
    std::cout << job.dump() << std::endl;
  } else {
    PrintJob(proto::JobFromJson(job));
  }
  return kExitOk;
}

int Watch(const JobArgs& a) {
  RpcClient client(a.server);
  const Json finished = WatchJob(client, a.job_id, a.quiet);
  if (a.json) {
    std::cout << finished.dump() << std::endl;
  } else {
    PrintJob(proto::JobFromJson(finished));
  }
  return ExitCodeOfJob(finished);
}

int Result(const JobArgs& a) {
  RpcClient client(a.server);
  const Json result = client.Call("job.result", JobIdParams(a.job_id));
  if (!a.output_path.empty()) {
    Json with_trace = result;
    Json trace = Json::array();
    for (const TraceRow& row : FetchTrace(client, a.job_id))
      trace.push_back(proto::TraceRowToJson(row));
    with_trace["trace"] = std::move(trace);
    WriteResultFile(a.output_path, with_trace,
                    client.Call("job.scene", JobIdParams(a.job_id))["scene"]);
  }
  PrintResult(result, a.json);
  return ExitCodeOfJob(result);
}

int Trace(const JobArgs& a) {
  RpcClient client(a.server);
  const std::vector<TraceRow> rows = FetchTrace(client, a.job_id);
  if (a.json) {
    // job.trace's answer (proto/RPC.md), every page of it: the whole trace, so next_after is
    // null.
    Json list = Json::array();
    for (const TraceRow& r : rows) list.push_back(proto::TraceRowToJson(r));
    Json out;
    out["rows"] = std::move(list);
    out["next_after"] = nullptr;
    std::cout << out.dump() << std::endl;
  } else if (a.csv) {
    std::cout << proto::TraceCsvHeader() << "\n";
    for (const TraceRow& r : rows) std::cout << proto::TraceRowToCsv(r) << "\n";
  } else if (proto::ProgressCountsSteps(
                 proto::JobFromJson(client.Call("job.get", JobIdParams(a.job_id))).strategy)) {
    // A fit's rows are its models, after so many Gauss-Newton steps; E is the one error
    // measure shown (proto/RUN.md), as `run` and `watch` show it.
    std::printf("%6s %10s %8s %12s\n", "model", "seconds", "steps", "E");
    for (const TraceRow& r : rows) {
      std::printf("%6d %10.3f %8lld %12.6g\n", r.generation, r.wall_seconds,
                  static_cast<long long>(r.evaluations), std::sqrt(r.best_normalized_error));
    }
  } else {
    std::printf("%10s %10s %12s %14s %12s %8s %6s\n", "generation", "seconds", "evaluations",
                "best cost", "E", "missing", "extra");
    for (const TraceRow& r : rows) {
      std::printf("%10d %10.3f %12lld %14.6g %12.6g %8s %6s\n", r.generation, r.wall_seconds,
                  static_cast<long long>(r.evaluations), r.best_cost,
                  std::sqrt(r.best_normalized_error),
                  r.missing < 0 ? "-" : std::to_string(r.missing).c_str(),
                  r.extra < 0 ? "-" : std::to_string(r.extra).c_str());
    }
  }
  return kExitOk;
}

// job.cancel and job.delete: the answer as JSON, or "job N <state>".
int ChangeJob(const JobArgs& a, const char* method) {
  RpcClient client(a.server);
  const Json r = client.Call(method, JobIdParams(a.job_id));
  if (a.json) {
    std::cout << r.dump() << std::endl;
  } else {
    std::cout << "job " << a.job_id << " " << r.value("state", std::string("deleted")) << "\n";
  }
  return kExitOk;
}

int Cancel(const JobArgs& a) {
  return ChangeJob(a, "job.cancel");
}
int Delete(const JobArgs& a) {
  return ChangeJob(a, "job.delete");
}

int List(const JobArgs& a) {
  RpcClient client(a.server);
  Json params;
  if (a.state) params["state"] = *a.state;
  if (a.label) params["label"] = *a.label;
  params["order"] = a.oldest_first ? "oldest" : "newest";
  if (a.cursor) params["cursor"] = *a.cursor;
  // Up to --limit jobs over as many pages as that takes; the cursor after the last one shown
  // goes on from there (`list --cursor N`).
  Json jobs = Json::array();
  Json next_cursor = nullptr;
  while (static_cast<int>(jobs.size()) < a.limit) {
    params["limit"] = std::min(1000, a.limit - static_cast<int>(jobs.size()));
    const Json page = client.Call("job.list", params);
    for (const Json& j : page["jobs"]) jobs.push_back(j);
    next_cursor = page["next_cursor"];
    if (next_cursor.is_null()) break;
    params["cursor"] = next_cursor;
  }
  if (a.json) {
    Json out;
    out["jobs"] = std::move(jobs);
    out["next_cursor"] = std::move(next_cursor);
    std::cout << out.dump() << std::endl;
    return kExitOk;
  }
  // E is the returned model's (its verdict's) once finished; while running, the best so far.
  std::printf("%6s  %-9s  %-13s  %-16s  %-20s  %-10s  %11s  %7s  %9s  %s\n", "id", "state",
              "verdict", "label", "scene", "strategy", "progress", "springs", "E", "exact");
  for (const Json& j : jobs) {
    const proto::JobRecord r = proto::JobFromJson(j);
    std::string progress = "-";
    std::string springs = "-";
    const std::string e = proto::JobErrorText(r);
    if (r.outcome) {
      springs = std::to_string(r.outcome->springs);
    } else if (r.progress) {
      progress = ProgressText(r);
    }
    std::printf("%6lld  %-9s  %-13s  %-16s  %-20s  %-10s  %11s  %7s  %9s  %s\n",
                static_cast<long long>(r.id), std::string(proto::JobStateName(r.state)).c_str(),
                r.outcome ? std::string(VerdictName(r.outcome->verdict)).c_str() : "-",
                r.label.c_str(), r.scene_name.c_str(), r.strategy.c_str(), progress.c_str(),
                springs.c_str(), e.c_str(), r.exact ? (*r.exact ? "yes" : "no") : "-");
  }
  if (std::any_of(jobs.begin(), jobs.end(),
                  [](const Json& j) { return j["outcome"].is_null() && !j["progress"].is_null(); }))
    std::cout << "(E~: the best so far of a job not finished)\n";
  if (!next_cursor.is_null())
    std::cerr << "more jobs: springfit list --cursor " << next_cursor.dump()
              << (a.oldest_first ? " --oldest-first" : "") << "\n";
  return kExitOk;
}

int Info(const JobArgs& a) {
  RpcClient client(a.server);
  const Json info = client.Call("server.info");
  if (a.json) {
    std::cout << info.dump() << std::endl;
    return kExitOk;
  }
  std::cout << info["name"].get<std::string>() << " " << info["version"].get<std::string>()
            << " (protocol " << info["protocol"] << ")\n"
            << "workers:           " << info["workers"] << " (" << info["max_running"]
            << " jobs at once)\n"
            << "jobs:              " << info["running"] << " running, " << info["queued"]
            << " queued\n"
            << "token required:    " << (info["auth_required"].get<bool>() ? "yes" : "no") << "\n"
            << "limits:\n";
  // One limit a line, as the daemon's flags name them (proto/RPC.md, "server.info").
  if (info["limits"].is_object()) {
    for (const auto& [key, value] : info["limits"].items()) {
      std::string name = key + ":";
      name.resize(std::max<std::size_t>(name.size() + 1, 24), ' ');
      std::cout << "  " << name << value.dump() << "\n";
    }
  }
  return kExitOk;
}

CLI::App* AddJobCommand(CLI::App& app, const char* name, const char* help, int& exit_code,
                        int (*body)(const JobArgs&), std::shared_ptr<JobArgs> args, bool takes_id) {
  auto* cmd = app.add_subcommand(name, help);
  if (takes_id)
    cmd->add_option("ID", args->job_id, "Job id (springfit submit prints it)")->required();
  cmd->add_flag("--json", args->json, "Print JSON (proto/RPC.md) instead of text");
  AddServerFlags(cmd, args->server);
  const std::string context = name;
  cmd->callback([args, body, context, &exit_code] {
    exit_code = RunReportingErrors(context, [&] { return body(*args); });
  });
  return cmd;
}

}  // namespace

void RegisterJobCommands(CLI::App& app, int& exit_code) {
  AddJobCommand(app, "status", "Show a job's state and progress", exit_code, Status,
                std::make_shared<JobArgs>(), true);
  {
    auto args = std::make_shared<JobArgs>();
    auto* cmd = AddJobCommand(app, "watch", "Follow a job's progress until it finishes", exit_code,
                              Watch, args, true);
    cmd->add_flag("-q,--quiet", args->quiet, "No progress line");
  }
  {
    auto args = std::make_shared<JobArgs>();
    auto* cmd = AddJobCommand(app, "result", "Print a finished job's result", exit_code, Result,
                              args, true);
    cmd->add_option("-o,--output", args->output_path,
                    "Also write the result with its trace as JSON");
  }
  {
    auto args = std::make_shared<JobArgs>();
    auto* cmd = AddJobCommand(app, "trace", "Print a job's trace (one row per stored generation)",
                              exit_code, Trace, args, true);
    cmd->add_flag("--csv", args->csv, "CSV as `springfit run --trace` writes it");
  }
  AddJobCommand(app, "cancel",
                "Cancel a preparing, queued or running job (a running one keeps its best so far)",
                exit_code, Cancel, std::make_shared<JobArgs>(), true);
  AddJobCommand(app, "delete", "Delete a finished job and everything stored with it", exit_code,
                Delete, std::make_shared<JobArgs>(), true);
  {
    auto args = std::make_shared<JobArgs>();
    auto* cmd = AddJobCommand(app, "list", "List jobs, newest first", exit_code, List, args, false);
    cmd->add_option("--cursor", args->cursor,
                    "Go on after this job id (the last list printed it when there were more)");
    cmd->add_flag("--oldest-first", args->oldest_first, "In submission order");
    cmd->add_option("--state", args->state, "Only jobs in this state")
        ->check(CLI::IsMember(StateNames()));
    cmd->add_option("--label", args->label, "Only jobs with this label");
    cmd->add_option("--limit", args->limit, "At most this many jobs")
        ->check(CLI::Range(1, 1000000))
        ->capture_default_str();
  }
  AddJobCommand(app, "info", "Show the server's version, workers, jobs and limits", exit_code, Info,
                std::make_shared<JobArgs>(), false);
}

}  // namespace springfit::cli
