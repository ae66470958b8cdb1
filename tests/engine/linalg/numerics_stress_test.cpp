// The seeded stress test of numerical verdicts (testing/numerics_stress.h): a bounded
// number of extreme scenes in CI, each with its own time bound; bench/numerics_stress runs
// 10,000 and more.
#include <cstdlib>
#include <vector>

#include <gtest/gtest.h>

#include "testing/numerics_stress.h"

namespace springfit {
namespace {

TEST(NumericsStress, ExtremeScenesGetHonestBoundedAnswers) {
  // 120 in the Release run; the sanitizer run (tests/fuzz/run_fuzz.sh) sets fewer.
  const char* count = std::getenv("SPRINGFIT_STRESS_SCENES");
  const int kScenes = count ? std::atoi(count) : 120;
  int refused = 0, checked = 0, svd_checks = 0;
  // Seeds 1..kScenes, and the ones the 10,000-scene bench run found wrong before their fix
  // (thin strips whose rest Cholesky passed with small pivots: modes missed).
  std::vector<std::uint64_t> seeds = {1328, 3156, 4935, 5722, 6467};
  for (std::uint64_t seed = 1; seed <= static_cast<std::uint64_t>(kScenes); ++seed)
    seeds.push_back(seed);
  for (const std::uint64_t seed : seeds) {
    const examples::StressOutcome o = examples::RunStressScene(seed, 2.0);
    EXPECT_FALSE(o.failed()) << "seed " << seed << " (" << o.kind << "): " << o.detail;
    refused += o.refused ? 1 : 0;
    checked += o.refused ? 0 : 1;
    svd_checks += o.svd_checks;
  }
  // Many scenes must be identified, not refused: otherwise the checks check nothing. Half of
  // these extreme scenes are refused with a reason (a mechanism reference, loads or
  // equilibria double precision cannot resolve; 47% over the 10,000 of bench/RESULTS.md).
  EXPECT_GE(checked, kScenes * 2 / 5) << refused << " refused";
  EXPECT_GE(svd_checks, kScenes);
}

TEST(NumericsStress, TheSceneOfASeedIsAlwaysTheSame) {
  const Scene a = examples::MakeStressScene(77), b = examples::MakeStressScene(77);
  EXPECT_EQ(a.rest, b.rest);
  EXPECT_EQ(a.reference.springs, b.reference.springs);
  EXPECT_NE(a.rest, examples::MakeStressScene(78).rest);
}

}  // namespace
}  // namespace springfit
