// Where a client command finds a result: a result file (`run -o`, `result -o`) or a job of the
// daemon (RESULT_OR_ID), and the scene it is a result of (render, export).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "client/rpc_client.h"
#include "engine/api/problem.h"
#include "proto/json_reader.h"
#include "proto/search_codec.h"

namespace springfit::cli {

struct ResultSource {
  std::string name;  // as given
  std::optional<std::int64_t> job_id;
};

// An existing file wins over a job id, so that a file named "12" can still be read. Throws
// InputError for neither.
ResultSource ParseResultSource(const std::string& text);

// A result file's JSON; throws InputError naming the file when it is not one.
proto::Json ReadResultFile(const std::string& path);

// The typed result; its errors name `where`.
proto::StoredResult TypedResult(const proto::Json& result, const std::string& where);

// A result with the problem of its scene: a file's own `scene_definition` (or `scene_path`),
// or the job's scene from the daemon. Checked to be a result of that scene.
struct ResultWithScene {
  proto::Json json;
  proto::StoredResult result;
  std::unique_ptr<Problem> problem;
  std::string where;  // "job N" or the file's name
};
ResultWithScene LoadResultWithScene(const std::string& text, const ServerOptions& server,
                                    const std::string& scene_path = "");

}  // namespace springfit::cli
