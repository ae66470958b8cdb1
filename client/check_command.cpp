// springfit check SCENE: validate a scene and summarise it.
#include <iostream>

#include "client/commands.h"
#include "client/exit_codes.h"
#include "client/error_reporting.h"
#include "engine/direct/identifiability.h"
#include "engine/problem.h"
#include "engine/search/search_options.h"
#include "proto/names.h"
#include "proto/scene_codec.h"

namespace springfit::cli {
namespace {

std::string PairList(const std::vector<NodePair>& pairs) {
  std::string out;
  for (const NodePair& p : pairs) out += " (" + std::to_string(p.first) + ", " + std::to_string(p.second) + ")";
  return out;
}

void PrintIdentifiability(const IdentifiabilityReport& report) {
  std::cout << "unseen springs:         " << report.unseen.size();
  if (!report.unseen.empty()) std::cout << " (no load case changes their length:" << PairList(report.unseen) << ")";
  std::cout << "\n";
  if (!report.groups_analysed) {
    std::cout << "dependent groups:       not analysed (more than " << IdentifiabilityOptions{}.max_genes
              << " seen genes)\n";
    return;
  }
  std::cout << "dependent groups:       " << report.groups.size();
  if (report.groups.empty()) std::cout << " (the load cases tell every seen spring apart)";
  std::cout << "\n";
  for (std::size_t g = 0; g < report.groups.size(); ++g) {
    const DependentGroup& group = report.groups[g];
    std::cout << "  group " << g << ": " << group.dependencies << " dependenc" << (group.dependencies == 1 ? "y" : "ies")
              << " among" << PairList(group.springs) << "\n";
    if (group.suggestion) std::cout << "    to separate them: " << group.suggestion->text << "\n";
  }
}

int Check(const std::string& file) {
  const Problem problem = Problem::Build(proto::LoadSceneFile(file));
  const Scene& s = problem.scene();
  std::cout << "scene:                  " << (s.name.empty() ? file : s.name) << "\n";
  if (!s.description.empty()) std::cout << "description:            " << s.description << "\n";
  std::cout << "dimension:              " << s.dimension << "\n"
            << "nodes:                  " << s.node_count() << "\n"
            << "candidate springs:      " << problem.candidates().size() << " ("
            << proto::CandidateKindName(s.candidates.kind) << ")\n"
            << "genes:                  " << problem.gene_count() << "\n"
            << "unidentifiable springs: " << problem.unidentifiable().size();
  if (!problem.unidentifiable().empty()) {
    std::cout << " (both nodes constrained in every load case:";
    for (int c : problem.unidentifiable()) {
      std::cout << " (" << problem.candidates().pairs[c].first << ", "
                << problem.candidates().pairs[c].second << ")";
    }
    std::cout << ")";
  }
  std::cout << "\n";
  PrintIdentifiability(AnalyseIdentifiability(problem));
  if (s.reference.kind == Reference::Kind::kMss) {
    std::cout << "reference:              mss, " << s.reference.springs.size() << " springs";
    if (problem.reference_mask()) {
      std::cout << ", all candidates (exact recovery is checkable)";
    } else {
      std::cout << ", " << problem.reference_non_candidates().size()
                << " not among the candidates (exact recovery impossible)";
    }
    std::cout << "\n";
  } else {
    std::cout << "reference:              positions given per load case\n";
  }
  std::cout << "training stiffness:     " << problem.training_stiffness() << "\n"
            << "load cases:             " << s.load_cases.size() << "\n";
  for (std::size_t k = 0; k < s.load_cases.size(); ++k) {
    const LoadCase& lc = s.load_cases[k];
    int forced = 0, displaced = 0;
    for (const NodalLoad& f : lc.forces) forced += static_cast<int>(f.nodes.size());
    for (const NodalLoad& d : lc.displacements) displaced += static_cast<int>(d.nodes.size());
    std::cout << "  [" << k << "] " << (lc.name.empty() ? "(unnamed)" : lc.name) << ": "
              << lc.fixed.size() << " fixed, " << displaced << " displaced, " << forced
              << " loaded\n";
  }
  if (problem.DisplacementOnly()) {
    std::cout << "  no load case applies a force: the data fix the stiffness only up to one factor\n";
  }
  const SearchOptions options = ResolveSearchOptions(s.search, problem.gene_count());
  std::cout << "search:                 strategy " << proto::StrategyName(options.strategy) << ", identifies "
            << (options.identify == Identify::kTopology ? "the topology (every spring at the training stiffness)"
                                                        : "the topology and each spring's stiffness")
            << "\n";
  return kExitOk;
}

}  // namespace

void RegisterCheck(CLI::App& app, int& exit_code) {
  auto* cmd = app.add_subcommand("check", "Validate a scene and print a summary (exit 2 if invalid)");
  auto file = std::make_shared<std::string>();
  cmd->add_option("SCENE", *file, "Scene file (JSON, proto/SCENE.md)")->required();
  cmd->callback([file, &exit_code] {
    exit_code = RunReportingErrors(*file, [&] { return Check(*file); });
  });
}

}  // namespace springfit::cli
