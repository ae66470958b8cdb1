// The long run of the numerical stress test (testing/numerics_stress.h): N seeded
// extreme scenes, each checked independently and run by strategy direct with a time limit,
// and the counts bench/RESULTS.md records.
//   numerics_stress --scenes 10000 [--first 1] [--max-seconds 5] [--verbose]
//   numerics_stress --write-scene SEED -o FILE.json   (a scene to reproduce with springfit)
#include <CLI/CLI.hpp>
#include <cctype>
#include <cstdio>
#include <fstream>
#include <map>
#include <string>

#include "proto/scene_codec.h"
#include "testing/numerics_stress.h"

int main(int argc, char** argv) {
  CLI::App app("numerics stress: seeded extreme scenes, independent checks, counts");
  std::uint64_t first = 1;
  int scenes = 1000;
  double max_seconds = 5.0;
  bool verbose = false;
  app.add_option("--first", first, "first seed");
  app.add_option("--scenes", scenes, "how many scenes")->check(CLI::PositiveNumber);
  app.add_option("--max-seconds", max_seconds, "direct's time limit per scene");
  app.add_flag("--verbose", verbose, "print every failure and refusal");
  std::uint64_t write_seed = 0;
  std::string output;
  app.add_option("--write-scene", write_seed, "write the scene of this seed and stop");
  app.add_option("-o", output, "the file --write-scene writes");
  CLI11_PARSE(app, argc, argv);
  if (write_seed != 0) {
    std::ofstream file(output);
    file << springfit::proto::SceneToJson(springfit::examples::MakeStressScene(write_seed)).dump(1)
         << "\n";
    if (!file) {
      std::fprintf(stderr, "numerics_stress: cannot write '%s'\n", output.c_str());
      return 1;
    }
    return 0;
  }

  int refused = 0, svd = 0, hangs = 0, non_finite = 0, false_mechanism = 0, inconsistent = 0,
      unbalanced = 0, scale = 0, silent = 0;
  double slowest = 0.0, total = 0.0;
  std::map<std::string, int> kinds, refusals;
  for (std::uint64_t seed = first; seed < first + static_cast<std::uint64_t>(scenes); ++seed) {
    const auto o = springfit::examples::RunStressScene(seed, max_seconds);
    ++kinds[o.kind];
    svd += o.svd_checks;
    total += o.seconds;
    slowest = std::max(slowest, o.seconds);
    if (o.refused) {
      ++refused;
      // The refusal's kind: its text after the path, numbers written as #, cut at 60.
      const std::string r = o.refusal;
      const auto colon = r.find(": ");
      std::string why;
      for (const char c : colon == std::string::npos ? r : r.substr(colon + 2)) {
        const bool digit = std::isdigit(static_cast<unsigned char>(c)) != 0;
        if (!digit || why.empty() || why.back() != '#') why += digit ? '#' : c;
      }
      why = why.substr(0, std::min<std::size_t>(why.size(), 60));
      ++refusals[why];
      if (verbose)
        std::printf("seed %llu refused: %s\n", static_cast<unsigned long long>(seed), r.c_str());
    }
    hangs += o.hang;
    non_finite += o.non_finite;
    false_mechanism += o.false_mechanism;
    inconsistent += o.inconsistent;
    unbalanced += o.unbalanced;
    scale += o.scale_dependent;
    silent += o.silent_wrong;
    if (o.failed())
      std::printf("seed %llu (%s) FAILED: %s\n", static_cast<unsigned long long>(seed),
                  o.kind.c_str(), o.detail.c_str());
  }
  std::printf("scenes %d (seeds %llu..%llu), kinds:", scenes,
              static_cast<unsigned long long>(first),
              static_cast<unsigned long long>(first + scenes - 1));
  for (const auto& [kind, count] : kinds) std::printf(" %s %d", kind.c_str(), count);
  std::printf("\nrefused with a clear error: %d\n", refused);
  for (const auto& [why, count] : refusals) std::printf("  %5d  %s...\n", count, why.c_str());
  std::printf("verdicts checked by SVD: %d\n", svd);
  std::printf(
      "hangs %d, NaN/Inf %d, false mechanism verdicts %d, inconsistent flags %d, "
      "unbalanced equilibria %d, scale-dependent errors %d, silent wrong answers %d\n",
      hangs, non_finite, false_mechanism, inconsistent, unbalanced, scale, silent);
  std::printf("seconds: total %.1f, slowest scene %.2f\n", total, slowest);
  return hangs + non_finite + false_mechanism + inconsistent + unbalanced + scale + silent == 0 ? 0
                                                                                                : 1;
}
