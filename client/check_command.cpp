// springfit check SCENE: validate a scene and summarise it.
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <optional>
#include <string>

#include <fmt/format.h>

#include "client/commands.h"
#include "client/error_reporting.h"
#include "client/exit_codes.h"
#include "client/scene_input.h"
#include "engine/api/analysis.h"
#include "engine/api/identify.h"
#include "engine/api/input_error.h"
#include "engine/api/problem.h"
#include "engine/api/scene.h"
#include "proto/names.h"
#include "proto/outcome_codec.h"
#include "proto/scene_codec.h"

namespace springfit::cli {
namespace {

// Node pairs, eight to an indented line (hundreds of them stay readable).
// Node pairs listed at most, three lines of eight: a mesh's held boundary has hundreds (issue 47
// item 7: 635 pairs over 80 lines), which `check --all-pairs` lists.
constexpr std::size_t kListedPairs = 24;

// The pairs eight to a line, the first kListedPairs unless `all`, then how many more.
std::string PairList(const std::vector<NodePair>& pairs, bool all) {
  std::string out;
  const std::size_t listed = all ? pairs.size() : std::min(pairs.size(), kListedPairs);
  for (std::size_t i = 0; i < listed; ++i) {
    out += (i % 8 == 0 ? "\n    " : " ");
    out += "(" + std::to_string(pairs[i].first) + ", " + std::to_string(pairs[i].second) + ")";
  }
  if (listed < pairs.size())
    out += "\n    ... and " + std::to_string(pairs.size() - listed) +
           " more (springfit check --all-pairs lists them)";
  return out;
}

// `held`: the springs between held nodes, listed above (unseen too, but counted apart).
void PrintIdentifiability(const IdentifiabilityReport& report, bool all_pairs, std::size_t held) {
  std::cout << "unseen springs:         " << report.unseen.size();
  if (held > 0) std::cout << " besides the " << held << " between held nodes";
  if (!report.unseen.empty())
    std::cout << " (no load case changes their length):" << PairList(report.unseen, all_pairs);
  std::cout << "\n";
  if (!report.groups_analysed) {
    std::cout << "dependent groups:       " << GroupsNotAnalysedText(report.not_analysed) << "\n";
    return;
  }
  std::cout << "dependent groups:       " << report.groups.size();
  if (report.groups.empty()) std::cout << " (the load cases tell every seen spring apart)";
  std::cout << "\n";
  for (std::size_t g = 0; g < report.groups.size(); ++g) {
    const DependentGroup& group = report.groups[g];
    std::cout << "  group " << g << ": " << group.dependencies << " dependenc"
              << (group.dependencies == 1 ? "y" : "ies") << " among"
              << PairList(group.springs, all_pairs) << "\n";
    if (group.suggestion) std::cout << "    to separate them: " << group.suggestion->text << "\n";
  }
}

// " UNIT" of a number, or nothing where the scene states no units (proto/SCENE.md, "Units").
std::string Unit(const std::optional<DerivedUnits>& units, std::string DerivedUnits::*which) {
  return units ? " " + (*units).*which : std::string();
}

std::string MaterialText(const Material& m, const std::optional<DerivedUnits>& units) {
  return fmt::format("{}, young {:.6g}{}, poisson {:.6g}", proto::MaterialModelName(m.model),
                     m.young, Unit(units, &DerivedUnits::modulus), m.poisson);
}

void PrintFemReference(const Scene& s, const std::optional<DerivedUnits>& units) {
  const FemReference& fem = s.reference.fem;
  const fem::MeshFacts facts = fem::MeshFactsOf(s);
  const double quality = facts.worst_quality;
  const int worst = facts.worst_element;
  std::cout << "reference:              fem, " << fem.elements.size()
            << (s.dimension == 2 ? " triangles" : " tetrahedra");
  if (s.dimension == 2) {
    std::cout << ", plane " << proto::PlaneModeName(fem.plane) << ", thickness " << fem.thickness
              << Unit(units, &DerivedUnits::length);
  }
  std::cout << "\n";
  if (fem.regions) {
    for (std::size_t m = 0; m < fem.materials.size(); ++m) {
      const auto count =
          std::count(fem.element_material.begin(), fem.element_material.end(), static_cast<int>(m));
      std::printf("  material %-14s", (std::to_string(m) + ":").c_str());
      std::fflush(stdout);
      std::cout << MaterialText(fem.materials[m], units) << " (" << count << " elements)\n";
    }
  } else {
    std::cout << "  material:             " << MaterialText(fem.materials[0], units) << "\n";
  }
  std::cout << "  " << (s.dimension == 2 ? "area x thickness:     " : "volume:               ")
            << facts.volume << (units ? " " + units->length + "^3" : std::string()) << "\n";
  std::cout << fmt::format("  smallest quality:     {:.3g} ({}; 1 = equilateral)\n", quality,
                           ElementNamed(s, static_cast<std::size_t>(worst)));
}

// The reference: its kind, and what it allows (exact recovery, the FEM mesh).
void PrintReference(const Problem& problem, const std::optional<DerivedUnits>& units) {
  const Scene& s = problem.scene();
  if (s.reference.kind == Reference::Kind::kMss) {
    std::cout << "reference:              mss, " << s.reference.springs.size() << " springs";
    if (problem.reference_mask()) {
      std::cout << ", all candidates (exact recovery is checkable)";
    } else {
      std::cout << ", " << problem.reference_non_candidates().size()
                << " not among the candidates (exact recovery impossible)";
    }
    std::cout << "\n";
  } else if (s.reference.kind == Reference::Kind::kFem) {
    PrintFemReference(s, units);
  } else {
    std::cout << "reference:              positions given per load case\n";
  }
}

// Each load case's supports and loads, and the warnings of the reference's solves under them.
void PrintLoadCases(const Problem& problem) {
  const Scene& s = problem.scene();
  for (std::size_t k = 0; k < s.load_cases.size(); ++k) {
    const LoadCase& lc = s.load_cases[k];
    int forced = 0, displaced = 0;
    for (const NodalLoad& f : lc.forces) forced += static_cast<int>(f.nodes.size());
    for (const NodalLoad& d : lc.displacements) displaced += static_cast<int>(d.nodes.size());
    std::cout << "  [" << k << "] " << (lc.name.empty() ? "(unnamed)" : lc.name) << ": "
              << lc.fixed.size() << " fixed, " << displaced << " displaced, " << forced
              << " loaded";
    if (!lc.tractions.empty())
      std::cout << ", " << lc.tractions.size() << " traction"
                << (lc.tractions.size() == 1 ? "" : "s");
    std::cout << "\n";
  }
  for (std::size_t k = 0; k < problem.load_cases().size(); ++k) {
    const auto& solve = problem.load_cases()[k].reference_solve;
    if (solve && solve->resolution > kReferenceResolutionWarning)
      std::cout << "  warning: under load_cases[" << k
                << "] round-off leaves the reference's displacements determined only to "
                << NumberText(solve->resolution, 2)
                << " of their size (a stiffness spread or nearly collinear springs make its "
                   "tangent nearly singular): normalised errors below that are noise\n";
    if (solve && !solve->stable)
      std::cout << "  warning: under load_cases[" << k
                << "] the reference's equilibrium is unstable (its tangent stiffness is not "
                   "positive definite there, like a straight column's past its buckling load): "
                   "the reference MSS would leave it at the slightest disturbance, and a model "
                   "fitted to it may buckle instead\n";
  }
}

// The strategy that runs (`default` is chosen per scene, ResolvedStrategy): which, what it
// finds and why.
void PrintSearch(const Problem& problem) {
  const Scene& s = problem.scene();
  const SearchOptions options = ResolveSearchOptions(s.search, problem.gene_count());
  const Strategy runs = ResolvedStrategy(options.strategy, problem.scene());
  const bool stiffness = runs == Strategy::kContinuous ||
                         options.identify == Identify::kTopologyAndStiffness ||
                         (options.strategy == Strategy::kDefault && runs == Strategy::kDirect);
  std::cout << "search:                 strategy " << proto::StrategyName(options.strategy);
  if (runs != options.strategy) std::cout << " (" << proto::StrategyName(runs) << " here)";
  std::cout << ", identifies "
            << (stiffness ? "the topology and each spring's stiffness"
                          : "the topology (every spring at the training stiffness)")
            << ", response " << proto::ResponseName(problem.response()) << "\n";
  if (runs != options.strategy)
    std::cout << "  why " << proto::StrategyName(runs) << ": "
              << DefaultStrategyReason(options.strategy, s) << "\n";
}

int Check(const SceneInput& input, bool all_pairs) {
  const std::string& file = input.path;
  const Problem problem = Problem::Build(SceneOf(input));
  const Scene& s = problem.scene();
  std::cout << "scene:                  " << (s.name.empty() ? file : s.name) << "\n";
  if (!s.description.empty()) std::cout << "description:            " << s.description << "\n";
  // The units the numbers below are in, as `run`'s summary says them.
  const std::optional<DerivedUnits> units =
      s.units ? std::optional<DerivedUnits>(DeriveUnits(*s.units)) : std::nullopt;
  if (units)
    std::cout << "units:                  " << proto::UnitsText(proto::UnitsToJson(*units)) << "\n";
  std::cout << "dimension:              " << s.dimension << "\n"
            << "nodes:                  " << s.node_count() << "\n"
            << "candidate springs:      " << problem.candidates().size() << " ("
            << proto::CandidateKindName(s.candidates.kind) << ")\n"
            << "genes:                  " << problem.gene_count() << "\n"
            << "between held nodes:     " << problem.unidentifiable().size();
  if (!problem.unidentifiable().empty()) {
    std::vector<NodePair> pairs;
    for (int c : problem.unidentifiable()) pairs.push_back(problem.candidates().pairs[c]);
    std::cout << " springs (both nodes held in every load case: "
              << proto::HeldSpringsText(s.reference.kind == Reference::Kind::kFem)
              << "):" << PairList(pairs, all_pairs);
  }
  std::cout << "\n";
  PrintIdentifiability(Identifiability(problem), all_pairs, problem.unidentifiable().size());
  for (const std::string& notice : SceneNotices(problem))
    std::cout << "notice:                 " << notice << "\n";
  // (The same line a run's verdict gives as a doubt: proto/RUN.md, "Doubts".)
  if (const auto strain = SmallStrainWarning(problem, s.search.load_size.value_or(0.0)))
    std::cout << "WARNING:                " << *strain << "\n";
  PrintReference(problem, units);
  std::cout << "training stiffness:     " << problem.training_stiffness()
            << Unit(units, &DerivedUnits::stiffness) << "\n"
            << "load cases:             " << s.load_cases.size() << "\n";
  PrintLoadCases(problem);
  if (problem.DisplacementOnly()) {
    std::cout
        << "  no load case applies a force: the data fix the stiffness only up to one factor\n";
  }
  PrintSearch(problem);
  return kExitOk;
}

}  // namespace

void RegisterCheck(CLI::App& app, int& exit_code) {
  auto* cmd =
      app.add_subcommand("check", "Validate a scene and print a summary (exit 2 if invalid)");
  auto input = std::make_shared<SceneInput>();
  AddSceneInput(cmd, *input);
  auto all_pairs = std::make_shared<bool>(false);
  cmd->add_flag("--all-pairs", *all_pairs,
                "list every node pair (unidentifiable, unseen, in a dependent group); by "
                "default the first 24 of each list and how many more");
  cmd->callback([input, all_pairs, &exit_code] {
    exit_code = RunReportingErrors(input->path, [&] { return Check(*input, *all_pairs); });
  });
}

}  // namespace springfit::cli
