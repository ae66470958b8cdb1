// springfit submit SCENE: queue an identification job on springfitd (README.md, "The daemon").
#include <iostream>
#include <optional>

#include "client/commands.h"
#include "client/error_reporting.h"
#include "client/exit_codes.h"
#include "client/remote_job.h"
#include "client/result_summary.h"
#include "client/scene_input.h"
#include "client/search_flags.h"
#include "engine/api/input_error.h"
#include "proto/names.h"
#include "proto/scene_codec.h"

namespace springfit::cli {
namespace {
using proto::Json;

struct SubmitArgs {
  ServerOptions server;
  SceneInput scene;
  std::string label;
  int priority = 0;
  SearchFlags search;
  std::string idempotency_key;
  bool wait = false;
  bool watch = false;
  bool json = false;
};

int Submit(const SubmitArgs& args) {
  Json scene = SceneJsonOf(args.scene);
  // The flags over the scene's search settings, read and written by the scene's own codec.
  SearchSettings settings =
      scene.contains("search") ? proto::SearchSettingsFromJson(scene["search"]) : SearchSettings{};
  ApplySearchFlags(args.search, settings);
  if (Json search = proto::SearchSettingsToJson(settings); search.empty()) {
    scene.erase("search");
  } else {
    scene["search"] = std::move(search);
  }
  Json params;
  params["scene"] = std::move(scene);
  if (!args.label.empty()) params["label"] = args.label;
  if (args.priority != 0) params["priority"] = args.priority;
  if (args.search.seed) params["seed"] = *args.search.seed;
  if (!args.idempotency_key.empty()) params["idempotency_key"] = args.idempotency_key;

  RpcClient client(args.server);
  // A large scene takes the daemon a while to prepare: its id is known (and the job listed,
  // and cancellable) from the start.
  client.SetPreparingListener([shown = false](const Json& notice) mutable {
    if (shown) return;
    shown = true;
    std::cerr << "job " << notice.value("job_id", Json(0)).get<std::int64_t>()
              << " preparing (its reference is being solved; interrupting this command drops "
                 "the submission, `springfit cancel` cancels it)"
              << std::endl;
  });
  const Json submitted = client.Call("job.submit", params);
  const Json& job = submitted["job"];
  const std::int64_t id = job["job_id"].get<std::int64_t>();
  // The id at once, on stderr, also before a wait: a pipeline's log has it even if the wait
  // is cut short, and stdout keeps only the job or the result.
  const std::string state = job["state"].get<std::string>();
  std::cerr << "job " << id
            << (!submitted["created"].get<bool>() ? " already submitted with this key"
                : state == "cancelled"            ? " cancelled while it was prepared"
                                                  : " queued")
            << " (" << job["scene"].get<std::string>() << ", " << job["genes"].get<int>()
            << " genes, strategy " << job["strategy"].get<std::string>() << ", seed "
            << job["seed"].get<std::uint64_t>() << ")" << std::endl;
  // The scene's notices, as `run` says them before it runs (a daemon before them sends none).
  if (submitted.contains("notices") && submitted["notices"].is_array())
    for (const Json& notice : submitted["notices"])
      if (notice.is_string())
        std::cerr << "springfit: notice: " << notice.get<std::string>() << std::endl;
  if (!args.wait && !args.watch) {
    if (args.json) {
      std::cout << submitted.dump() << std::endl;
    } else {
      std::cout << id << std::endl;
    }
    return kExitOk;
  }
  const Json finished = WatchJob(client, id, !args.watch);
  const std::string final_state = finished["state"].get<std::string>();
  if (final_state == "failed") {
    std::cerr << "springfit: job " << id
              << " failed: " << finished.value("error", Json("")).get<std::string>() << "\n";
    return kExitJobFailed;
  }
  try {
    PrintResult(client.Call("job.result", JobIdParams(id)), args.json);
  } catch (const RemoteError&) {
    std::cerr << "springfit: job " << id << " " << final_state << " before it ran\n";
  }
  return ExitCodeOfJob(finished);
}

}  // namespace

void RegisterSubmit(CLI::App& app, int& exit_code) {
  auto* cmd =
      app.add_subcommand("submit", "Queue an identification job on springfitd; prints its id");
  auto args = std::make_shared<SubmitArgs>();
  AddSceneInput(cmd, args->scene);
  cmd->add_option("--label", args->label, "A label to find the job by (job.list --label)");
  cmd->add_option("--priority", args->priority, "Higher runs first (default 0)")
      ->check(CLI::Range(-1000, 1000));
  AddSearchFlags(cmd, args->search);
  cmd->add_option("--idempotency-key", args->idempotency_key,
                  "Submitting again with the same key returns the same job instead of a new one");
  auto* wait =
      cmd->add_flag("--wait", args->wait, "Wait for the job to finish, then print its result");
  cmd->add_flag("--watch", args->watch,
                "Show its progress until it finishes, then print its result")
      ->excludes(wait);
  cmd->add_flag("--json", args->json, "Print JSON: the job (or, with --wait/--watch, the result)");
  AddServerFlags(cmd, args->server);
  cmd->callback([args, &exit_code] {
    exit_code = RunReportingErrors(args->scene.path, [&] { return Submit(*args); });
  });
}

}  // namespace springfit::cli
