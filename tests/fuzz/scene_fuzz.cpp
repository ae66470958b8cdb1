// libFuzzer target for the scene loader (proto/scene_codec.h) and the problem build behind it
// (candidate springs, reference equilibria), the path every job.submit takes.
//
// Bad input must end as an InputError naming a path; anything else escaping (another
// exception, a crash, a sanitizer report, a hang) is a bug. Scenes the daemon would refuse
// by its default limits are not built, so that one input cannot run for minutes.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "engine/input_error.h"
#include "engine/problem.h"
#include "proto/scene_codec.h"

namespace {
constexpr int kMaxNodes = 200;         // enough for the examples; keeps each input fast
constexpr int kMaxGenerations = 1000;  // not run here, but checked like the daemon does
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    auto scene = springfit::proto::SceneFromText(text);
    if (scene.node_count() > kMaxNodes || scene.search.max_generations > kMaxGenerations) return 0;
    const auto problem = springfit::Problem::Build(std::move(scene));
    if (problem.gene_count() < 0) std::abort();
  } catch (const springfit::InputError& e) {
    if (std::string_view(e.what()).empty()) std::abort();  // every error says something
  }
  return 0;
}
