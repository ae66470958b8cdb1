// libFuzzer target for the scene loader (proto/scene_codec.h) and the problem build behind it
// (candidate springs, reference equilibria), the path every job.submit takes.
//
// Bad input must end as an InputError naming a path; anything else escaping (another
// exception, a crash, a sanitizer report, a hang) is a bug. A scene that loads must survive
// the round trip SceneToJson -> SceneFromJson unchanged (job.scene and result files rely on
// it). Only scenes of at most 200 nodes are built (the daemon allows far more), so that no
// single input runs for long.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "engine/api/problem.h"
#include "engine/runtime/input_error.h"
#include "proto/scene_codec.h"

namespace {
constexpr int kMaxNodes = 200;         // enough for the examples; keeps each input fast
constexpr int kMaxGenerations = 1000;  // nothing is run here; only the daemon's default bound
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    auto scene = springfit::proto::SceneFromText(text);
    const auto written = springfit::proto::SceneToJson(scene);
    if (springfit::proto::SceneToJson(springfit::proto::SceneFromJson(written)) != written)
      std::abort();
    if (scene.node_count() > kMaxNodes || scene.search.max_generations > kMaxGenerations) return 0;
    (void)springfit::Problem::Build(std::move(scene));
  } catch (const springfit::InputError& e) {
    if (std::string_view(e.what()).empty()) std::abort();  // every error says something
  }
  return 0;
}
