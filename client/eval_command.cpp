// springfit eval SCENE [--topology reference|all|FILE] [--json]: the cost of one topology.
#include <chrono>
#include <cstdio>
#include <iostream>

#include "client/commands.h"
#include "client/error_reporting.h"
#include "client/exit_codes.h"
#include "client/scene_input.h"
#include "engine/api/input_error.h"
#include "engine/api/problem.h"
#include "proto/evaluation_codec.h"
#include "proto/names.h"
#include "proto/scene_codec.h"

namespace springfit::cli {
namespace {

struct EvalArgs {
  SceneInput scene;
  std::string topology = "reference";
  bool json = false;
};

std::vector<std::uint8_t> ChooseTopology(const Problem& problem, const std::string& topology) {
  if (topology == "reference") {
    if (!problem.reference_mask()) {
      const Reference::Kind kind = problem.scene().reference.kind;
      throw InputError("--topology",
                       kind == Reference::Kind::kMss
                           ? "the reference has springs that are not candidates"
                       : kind == Reference::Kind::kFem
                           ? "the reference is an FEM model: it has no spring topology (use "
                             "--topology all or FILE)"
                           : "the reference is given as positions: it has no topology");
    }
    return *problem.reference_mask();
  }
  if (topology == "all") return std::vector<std::uint8_t>(problem.candidates().size(), 1);
  try {
    return proto::TopologyFromJson(problem, proto::ParseJson(proto::ReadFile(topology)));
  } catch (const InputError& e) {
    throw InputError(topology + (e.path().empty() ? "" : ": " + e.path()),
                     std::string(e.what()).substr(e.path().empty() ? 0 : e.path().size() + 2));
  }
}

int Eval(const EvalArgs& args) {
  const Problem problem = Problem::Build(SceneOf(args.scene));
  const std::vector<std::uint8_t> mask = ChooseTopology(problem, args.topology);
  CostOptions cost_options;
  cost_options.solve_cases_of_mechanisms = true;  // a per-case report of every case
  CostFunction cost(problem, cost_options);
  const auto start = std::chrono::steady_clock::now();
  const Evaluation e = cost.EvaluateMask(mask);
  const double seconds = SecondsSince(start);
  int springs = 0;
  for (std::uint8_t bit : mask) springs += bit;

  if (args.json) {
    proto::Json j;
    j["topology"] = args.topology;
    j["springs"] = springs;
    auto body = proto::EvaluationToJson(problem, e);
    for (auto& [key, value] : body.items()) j[key] = value;
    j["wall_seconds"] = seconds;
    std::cout << proto::DumpCompact(j);
    return kExitOk;
  }
  std::printf("topology:          %s (%d springs)\n", args.topology.c_str(), springs);
  std::printf("cost:              %.6g\n", e.cost);
  std::printf("normalized error:  %.6g\n", e.normalized_error);
  std::printf("mechanism:         %s", e.mechanism ? "yes" : "no");
  if (e.mechanism) std::printf(" (%d modes over all load cases: penalised)", e.mechanism_modes);
  std::printf("\nevaluation time:   %.1f us\n\n", seconds * 1e6);
  std::printf("%-4s %-18s %-12s %-12s %-14s %5s %5s %10s\n", "case", "name", "cost", "norm. error",
              "termination", "iter", "proj", "residual");
  for (std::size_t k = 0; k < e.load_cases.size(); ++k) {
    const LoadCaseEvaluation& lc = e.load_cases[k];
    std::printf("%-4zu %-18s %-12.4g %-12.4g %-14s %5d %5d %10.2e\n", k,
                problem.scene().load_cases[k].name.c_str(), lc.cost, lc.normalized_error,
                std::string(proto::TerminationName(lc.solve.termination)).c_str(),
                lc.solve.iterations, lc.solve.projected_steps, lc.solve.final_residual);
  }
  for (std::size_t k = 0; k < e.load_cases.size(); ++k) {
    const int near = e.load_cases[k].solve.near_mechanism_modes;
    if (near > 0 && e.load_cases[k].solve.termination != Termination::kMechanism)
      std::printf(
          "case %zu: rigid, but along %d directions its stiffness is below 1e-10 of its stiffest "
          "(near a mechanism): double precision may not resolve its equilibrium\n",
          k, near);
  }
  return kExitOk;
}

}  // namespace

void RegisterEval(CLI::App& app, int& exit_code) {
  auto* cmd = app.add_subcommand("eval", "Evaluate the identification cost of one topology");
  auto args = std::make_shared<EvalArgs>();
  AddSceneInput(cmd, args->scene);
  cmd->add_option("--topology", args->topology,
                  "reference (the reference MSS's springs), all (every candidate), or a topology "
                  "file {\"springs\": [[i, j], ...]}")
      ->capture_default_str();
  cmd->add_flag("--json", args->json, "Print one JSON object (proto/EVAL.md)");
  cmd->callback([args, &exit_code] {
    exit_code = RunReportingErrors(args->scene.path, [&] { return Eval(*args); });
  });
}

}  // namespace springfit::cli
