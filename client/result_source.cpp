#include "client/result_source.h"

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "client/remote_job.h"
#include "engine/api/input_error.h"
#include "proto/scene_codec.h"

namespace springfit::cli {

using proto::Json;

ResultSource ParseResultSource(const std::string& text) {
  ResultSource s{text, std::nullopt};
  if (std::filesystem::exists(text)) return s;
  const bool digits =
      !text.empty() && text.size() < 19 &&
      std::all_of(text.begin(), text.end(), [](unsigned char c) { return std::isdigit(c) != 0; });
  if (!digits) throw InputError("", text + ": no such file (and not a job id)");
  s.job_id = std::stoll(text);
  return s;
}

Json ReadResultFile(const std::string& path) {
  Json j;
  try {
    j = proto::ParseJson(proto::ReadFile(path));
  } catch (const InputError& e) {
    throw InputError("", path + ": " + e.what());
  }
  if (!j.is_object() || !j.contains("springs") || !j.contains("strategy")) {
    throw InputError("", path + ": not a result file (springfit run -o, springfit result -o)");
  }
  return j;
}

proto::StoredResult TypedResult(const Json& result, const std::string& where) {
  try {
    return proto::StoredResultFromJson(result);
  } catch (const InputError& e) {
    throw InputError("", where + ": " + e.what());
  }
}

ResultWithScene LoadResultWithScene(const std::string& text, const ServerOptions& server,
                                    const std::string& scene_path) {
  const ResultSource source = ParseResultSource(text);
  ResultWithScene out;
  Json scene_json;
  if (source.job_id) {
    RpcClient client(server);
    out.json = client.Call("job.result", JobIdParams(*source.job_id));
    if (scene_path.empty())
      scene_json = client.Call("job.scene", JobIdParams(*source.job_id))["scene"];
    out.where = "job " + std::to_string(*source.job_id);
  } else {
    out.json = ReadResultFile(source.name);
    if (scene_path.empty()) {
      if (!out.json.contains("scene_definition")) {
        throw InputError(
            "", source.name +
                    " does not contain its scene (it was written by an older springfit or by "
                    "--json): pass --scene SCENE.json");
      }
      scene_json = out.json["scene_definition"];
    }
    out.where = std::filesystem::path(source.name).filename().string();
  }
  out.result = TypedResult(out.json, out.where);
  Scene scene =
      scene_path.empty() ? proto::SceneFromJson(scene_json) : proto::LoadSceneFile(scene_path);
  out.problem = std::make_unique<Problem>(std::move(scene));
  proto::ExpectResultOfScene(out.result, *out.problem);
  return out;
}

}  // namespace springfit::cli
