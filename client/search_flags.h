// The search options `run` and `submit` both take on the command line, defined once: the
// same names, checks and help, applied over the scene's own `search` settings.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "engine/api/scene.h"
#include "proto/json_reader.h"

namespace springfit::cli {

struct SearchFlags {
  std::optional<std::string> strategy;
  std::optional<std::string> identify;
  std::optional<std::uint64_t> seed;
  std::optional<int> generations;
  std::optional<double> time_limit;
  std::optional<int> stall;
  std::optional<std::string> response;
  std::optional<int> max_springs;
  std::optional<std::string> regularization;
  std::optional<std::string> probes;
  std::optional<double> target_error;
  std::optional<double> max_spread;
  std::optional<double> load_size;
};

void AddSearchFlags(CLI::App* command, SearchFlags& flags);
// Over a scene's search settings: `run`'s scene, and `submit`'s before it is encoded (the seed
// travels as job.submit's own parameter).
void ApplySearchFlags(const SearchFlags& flags, SearchSettings& settings);

}  // namespace springfit::cli
