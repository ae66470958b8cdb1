// springfit export RESULT_OR_ID -o FILE: the identified model in a simulator's or viewer's
// format, chosen by the file's extension (io/model_writers.h, proto/MODEL.md).
#include <iostream>
#include <memory>

#include <fmt/format.h>

#include "client/commands.h"
#include "client/error_reporting.h"
#include "client/exit_codes.h"
#include "client/remote_job.h"
#include "client/result_source.h"
#include "engine/api/analysis.h"
#include "engine/api/input_error.h"
#include "io/model_facts.h"
#include "io/model_writers.h"
#include "io/spring_model.h"

namespace springfit::cli {
namespace {

struct ExportArgs {
  ServerOptions server;
  std::string source;
  std::string output;
  std::string scene_path;
  io::ModelOptions model;
  io::SofaOptions sofa;
  std::vector<double> gravity;
  std::vector<std::string> sofa_flags_given;  // for a refusal when the output is not .scn
};

// The facts a simulator needs, one line (proto/MODEL.md, "Simulator facts").
std::string FactsLine(const io::SpringModel& model) {
  const auto& f = model.facts;
  // Stiffness in force / length where the scene states its units.
  const std::string k_unit = model.units ? " " + model.units->stiffness : "";
  std::string text = fmt::format(
      "stiffness {:.4g} to {:.4g}{}, median {:.4g}{} (spread {:.3g}) over the {} springs in the "
      "file; {} dead springs (below {:.4g}{}: {:g} x the fitted springs' median {:.4g}{}){}",
      f.min_stiffness, f.max_stiffness, k_unit, f.median_stiffness, k_unit,
      f.min_stiffness > 0.0 ? f.max_stiffness / f.min_stiffness : 0.0, model.springs.size(), f.dead,
      f.dead_threshold, k_unit, f.dead_fraction, f.fitted_median_stiffness, k_unit,
      f.dead == 0      ? ""
      : f.dead_dropped ? ", left out"
                       : ", kept and flagged");
  // Mass in the unit the scene's length and force imply, time in seconds; bare numbers where
  // the scene states no units (they are then in whatever units its numbers were).
  const std::string mass_unit = model.units ? " " + model.units->mass : "";
  const std::string time_unit = model.units ? " " + model.units->time : "";
  if (f.total_mass)
    text += fmt::format("; total mass {:.4g}{} ({})", *f.total_mass, mass_unit, model.mass_source);
  else
    text += "; no masses (give a density in the scene's material, --density or --node-mass)";
  if (f.stable_time_step)
    text +=
        fmt::format("; stable explicit time step at most {:.4g}{}", *f.stable_time_step, time_unit);
  return text;
}

// What the result says of the model, in the words `run` and `result` use: its verdict line,
// and the generalised eigenvalues that bound its error under every load on the user's supports.
// Empty for a result written before it had a verdict.
std::string JudgementLine(const proto::StoredResult& result) {
  if (!result.outcome) return "";
  std::string text = "verdict " + result.outcome->Headline();
  if (result.lambda_min && result.lambda_max)
    text += fmt::format(
        "; generalised eigenvalues of (K_model, K_ref) on the user's supports in [{:.3g}, {:.3g}]",
        *result.lambda_min, *result.lambda_max);
  if (const std::string what = result.outcome->WhatToTry(); !what.empty())
    text += "; what to try: " + what;
  return text;
}

int Export(const ExportArgs& a) {
  // The format first: an unknown extension is refused before anything is read or fetched.
  const io::ModelFormat format = io::ModelFormatOfPath(a.output);
  if (format != io::ModelFormat::kSofa && !a.sofa_flags_given.empty())
    throw InputError(a.sofa_flags_given.front(), "applies to a SOFA scene (.scn); " + a.output +
                                                     " is " +
                                                     std::string(io::ModelFormatName(format)));
  a.model.Validate();
  a.sofa.Validate();
  const ResultWithScene loaded = LoadResultWithScene(a.source, a.server, a.scene_path);
  const io::SpringModel model = io::ModelOfResult(*loaded.problem, loaded.result, a.model);
  io::WriteModelFile(model, a.output, a.sofa);
  int undetermined = 0, not_analysed = 0;
  for (const auto& s : model.springs) {
    undetermined += s.identified == io::SpringModel::Identified::kNo;
    not_analysed += s.identified == io::SpringModel::Identified::kNotAnalysed;
  }
  std::cout << a.output << ": " << io::ModelFormatName(format) << ", " << model.node_count()
            << " nodes, " << model.springs.size() << " springs";
  // (One name for one thing, as check, run and the dashboard say it: the springs between held
  // nodes, then those in groups the load cases cannot tell apart.)
  const int held = static_cast<int>(loaded.result.unidentifiable.size());
  if (undetermined > 0) {
    std::cout << " (" << undetermined << " not determined by the data: ";
    if (held > 0) std::cout << held << " between held nodes" << (undetermined > held ? ", " : "");
    if (undetermined > held) std::cout << undetermined - held << " in dependent groups";
    std::cout << ")";
  }
  if (not_analysed > 0)
    std::cout << " (whether the data determine " << not_analysed
              << " of them is not known: dependent groups "
              << GroupsNotAnalysedText(model.groups_not_analysed) << ")";
  std::cout << ", from " << loaded.where << "\n" << a.output << ": " << FactsLine(model) << "\n";
  if (const std::string judged = JudgementLine(loaded.result); !judged.empty())
    std::cout << a.output << ": " << judged << "\n";
  std::cout << a.output << ": " << io::JudgedText(model) << "\n";
  return kExitOk;
}

}  // namespace

void RegisterExport(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ExportArgs>();
  auto* cmd = app.add_subcommand(
      "export",
      "Write the identified model for a simulator or viewer: .vtk, .vtu (ParaView), .msh "
      "(Gmsh), .scn (SOFA) or .json, by the output's extension (proto/MODEL.md)");
  cmd->add_option("RESULT_OR_ID", args->source, "A result file (run -o, result -o) or a job id")
      ->required();
  cmd->add_option("-o,--output", args->output, "The model file to write")->required();
  cmd->add_option("--scene", args->scene_path,
                  "The scene, for a result file that does not carry it");
  cmd->add_option("--density", args->model.density,
                  "Mass per volume lumped on the FEM mesh's nodes (default: the materials' "
                  "density, when the scene states it)");
  cmd->add_option("--node-mass", args->model.node_mass, "Every node this mass (any scene)");
  cmd->add_option("--dead-fraction", args->model.dead_fraction,
                  "Springs below this fraction of the median stiffness are dead: flagged, or "
                  "left out with --drop-dead")
      ->capture_default_str();
  cmd->add_flag("--drop-dead", args->model.drop_dead, "Leave the dead springs out of the model");
  // The SOFA scene's own (.scn only).
  const auto sofa = [&](CLI::Option* option) {
    option->each([args, name = option->get_name()](const std::string&) {
      args->sofa_flags_given.push_back(name);
    });
    return option;
  };
  sofa(cmd->add_option("--sofa-version", args->sofa.release,
                       "The SOFA release whose components the .scn uses: v23.06, v23.12, v24.06, "
                       "v24.12, v25.06, v25.12 or v26.06")
           ->capture_default_str());
  sofa(cmd->add_option("--case", args->sofa.load_case,
                       "The load case whose supports and forces the .scn applies (default: the "
                       "first)"));
  sofa(cmd->add_flag("--dynamic", args->sofa.dynamic,
                     "Implicit Euler time steps with Rayleigh damping instead of a static solve "
                     "(needs masses)"));
  sofa(cmd->add_option("--rayleigh-stiffness", args->sofa.rayleigh_stiffness,
                       "--dynamic: damping proportional to the stiffness")
           ->capture_default_str());
  sofa(cmd->add_option("--rayleigh-mass", args->sofa.rayleigh_mass,
                       "--dynamic: damping proportional to the mass")
           ->capture_default_str());
  sofa(cmd->add_option("--dt", args->sofa.time_step, "The scene's time step")
           ->capture_default_str());
  sofa(cmd->add_option("--gravity", args->gravity, "Gravity, 2 or 3 components (needs masses)")
           ->expected(2, 3)
           ->delimiter(','));
  AddServerFlags(cmd, args->server);
  cmd->callback([args, &exit_code] {
    if (!args->gravity.empty())
      for (std::size_t c = 0; c < args->gravity.size(); ++c)
        args->sofa.gravity[c] = args->gravity[c];
    exit_code = RunReportingErrors("export", [&] { return Export(*args); });
  });
}

}  // namespace springfit::cli
