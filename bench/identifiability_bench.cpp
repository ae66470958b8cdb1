// The identifiability report at scale (engine/direct/identifiability.h): the sparse QR of the
// force balance over the seen genes, its confirmation and the groups' circuits, timed on each
// scene; peak memory from /usr/bin/time around the run (bench/RESULTS.md, "Identifiability at
// scale").
//
//   /usr/bin/time -f "%e s %M KB" build/bench/identifiability_bench examples/fem-block-3d.json
//
// --max-genes raises the report's bound (IdentifiabilityOptions::max_genes) to measure larger
// scenes than a run analyses; --max-suggestion-size 0 leaves the suggested load cases out, to
// measure what they cost.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "engine/api/problem.h"
#include "engine/direct/identifiability.h"
#include "proto/scene_codec.h"

namespace springfit {
namespace {

using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

int Run(int argc, char** argv) {
  CLI::App app{"The identifiability report at scale"};
  std::vector<std::string> files;
  IdentifiabilityOptions options;
  app.add_option("scenes", files, "Scene files")->required();
  app.add_option("--max-genes", options.max_genes, "Seen genes analysed at most")
      ->capture_default_str();
  app.add_option("--max-suggestion-size", options.max_suggestion_size,
                 "A group's springs x dependencies at most to get a suggested load case (0: none)")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  for (const std::string& file : files) {
    auto start = Clock::now();
    const Problem problem(proto::LoadSceneFile(file));
    const double prepare = Seconds(start);
    start = Clock::now();
    const IdentifiabilityReport report = AnalyseIdentifiability(problem, options);
    const double analyse = Seconds(start);
    int dependencies = 0;
    std::size_t springs = 0;
    for (const DependentGroup& g : report.groups) {
      dependencies += g.dependencies;
      springs += g.springs.size();
    }
    std::printf("%s: %d genes, %zu unseen; prepared in %.2f s, analysed in %.2f s: ",
                problem.scene().name.c_str(), problem.gene_count(), report.unseen.size(), prepare,
                analyse);
    if (!report.groups_analysed) {
      std::printf("%s\n", GroupsNotAnalysedText(report.not_analysed).c_str());
      continue;
    }
    const auto suggested = std::count_if(report.groups.begin(), report.groups.end(),
                                         [](const DependentGroup& g) { return g.suggestion; });
    std::printf("rank %d, %d dependencies in %zu groups of %zu springs, %td with a suggestion\n",
                report.rank, dependencies, report.groups.size(), springs, suggested);
  }
  return 0;
}

}  // namespace
}  // namespace springfit

int main(int argc, char** argv) {
  return springfit::Run(argc, argv);
}
