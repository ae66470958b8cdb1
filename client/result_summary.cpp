#include "client/result_summary.h"

#include "io/model_facts.h"

#include <cmath>

#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

#include "proto/outcome_codec.h"
#include "proto/scene_codec.h"
#include "proto/search_codec.h"

namespace springfit::cli {
namespace {

// A JSON number to 3 significant digits, a non-finite one's spelling ("inf"), "-" for none.
std::string ShortNumber(const proto::Json& j) {
  if (j.is_string()) return j.get<std::string>();
  return j.is_number() ? fmt::format("{:.3g}", j.get<double>()) : std::string("-");
}

void PrintPairs(std::ostream& out, const char* label, const proto::Json& pairs) {
  if (!pairs.is_array() || pairs.empty()) return;
  out << "  " << label << ":";
  for (const proto::Json& p : pairs)
    out << " (" << p[0].get<long long>() << ", " << p[1].get<long long>() << ")";
  out << "\n";
}

// The verdict first (a result's, as every summary shows it), then the scene's notices.
void PrintVerdict(const proto::Json& r, std::ostream& out) {
  if (!r.contains("outcome") || !r["outcome"].is_object()) return;
  PrintOutcome(proto::OutcomeFromJson(r["outcome"], "outcome"), out);
  if (r.contains("notices") && r["notices"].is_array())
    for (const proto::Json& notice : r["notices"])
      if (notice.is_string()) out << "notice:            " << notice.get<std::string>() << "\n";
}

}  // namespace

void PrintOutcome(const Outcome& o, std::ostream& out) {
  out << "verdict:           " << o.Headline() << "\n";
  for (const std::string& line : o.unmet) out << "WARNING:           " << line << "\n";
  for (const std::string& line : o.doubts) out << "WARNING:           " << line << "\n";
  if (const std::string what = o.WhatToTry(); !what.empty())
    out << "what to try:       " << what << "\n";
  if (!o.reason.empty()) out << "NO USABLE MODEL:   " << o.reason << "\n";
}

namespace {

// The probe fit's nonlinear stage, where it ran (a nonlinear response): its steps, its cases and
// the choosing error (at the load range's sizes, with the simulator's spring law) it began and
// ended at, beside the closed-form baseline's.
void PrintNonlinearFit(const proto::Json& fit, std::ostream& out) {
  if (!fit.contains("nonlinear") || !fit["nonlinear"].is_object()) return;
  const proto::Json& n = fit["nonlinear"];
  std::string sizes;
  for (const auto& a : n.value("amplitudes", proto::Json::array()))
    sizes += (sizes.empty() ? "" : ", ") + fmt::format("{:.0f}", 100.0 * a.get<double>());
  const auto number = [&n](const char* key) {
    return n.contains(key) && n[key].is_number() ? fmt::format("{:.3g}", n[key].get<double>())
                                                 : std::string("-");
  };
  out << "nonlinear fit:     " << n.value("gauss_newton_steps", 0) << " Gauss-Newton steps on "
      << n.value("fitted_cases", 0) << " equilibria (the fitted probes at " << sizes
      << "% of the named loads, nonlinear springs): choosing E "
      << number("start_choosing_rms_error") << " at rest-linear fit, "
      << number("choosing_rms_error") << " returned (baseline "
      << number("baseline_choosing_rms_error") << ")" << proto::NonlinearFitNotes(n) << "\n";
}

// How the run went: the scene and job, the verdict, the strategy and its stop, its work.
void PrintRun(const proto::Json& r, bool continuous, std::ostream& out) {
  out << "scene:             " << r.value("scene", std::string()) << "\n";
  // The units the numbers are in, where the scene states them (proto/SCENE.md, "Units").
  if (const std::string units = proto::UnitsText(r.value("units", proto::Json())); !units.empty())
    out << "units:             " << units << "\n";
  if (r.contains("job_id"))
    out << "job:               " << r["job_id"].get<long long>() << " ("
        << r.value("state", std::string()) << ")\n";
  PrintVerdict(r, out);
  out << "strategy:          " << r.value("strategy", std::string());
  if (r.contains("ran") && r["ran"] != r["strategy"])
    out << " (ran " << r["ran"].get<std::string>() << ")";
  out << " (seed " << r.value("seed", std::uint64_t{0}) << ")\n";
  if (r.contains("identify"))
    out << "identified:        " << r.value("identify", std::string()) << "\n";
  if (r.contains("response"))
    out << "response:          " << r.value("response", std::string()) << "\n";
  const std::string stop = r.value("stop", std::string());
  // A run without an answer says why and what to try, whatever the strategy.
  const bool no_answer =
      stop == "mechanism" || stop == "no_equilibrium" || stop == "not_reproduced";
  // (A continuous run stopped before its fit has no `continuous` details, and its message says
  // what it returns.)
  if (continuous || no_answer || r.value("ran", std::string()) == "continuous") {
    out << "stopped:           " << stop << ": " << r.value("stop_message", std::string()) << "\n";
  } else {
    out << "stopped:           " << r.value("stop", std::string()) << " after "
        << r.value("generations", 0) << " generations (best found in generation "
        << r.value("best_generation", 0) << ")\n";
  }
  const bool fitted_to_probes = r.contains("generalization") && r["generalization"].is_object() &&
                                r["generalization"].value("fitted_to_probes", false);
  if (continuous && fitted_to_probes) {
    // (The probe fit counts its accepted Gauss-Newton steps; it evaluates no genome.)
    out << "steps:             " << r["continuous"].value("steps", 0LL)
        << " (Gauss-Newton steps of the probe fit)\n";
    PrintNonlinearFit(r["generalization"].value("fit", proto::Json::object()), out);
  } else if (continuous) {
    out << "steps:             " << r.value("evaluations", 0LL)
        << " (trust-region steps: the fit, the path's refits, the returned model's refit)\n";
  } else {
    out << "evaluations:       " << r.value("evaluations", 0LL) << " ("
        << r.value("cache_hits", 0LL) << " from the cache)\n";
  }
  out << "wall time:         " << fmt::format("{:.3f}", r.value("wall_seconds", 0.0)) << " s";
  if (continuous && r["continuous"].contains("model_seconds")) {
    out << " (the model at "
        << fmt::format("{:.3f}", r["continuous"]["model_seconds"].get<double>())
        << " s, then its held-out error)";
  }
  out << "\n";
  if (r.contains("direct_phase") && r["direct_phase"].is_object()) {
    const proto::Json& phase = r["direct_phase"];
    out << "direct seed:       " << fmt::format("{:.3f}", phase.value("seconds", 0.0)) << " s, E "
        << fmt::format("{:.4g}", std::sqrt(phase.value("normalized_error", 0.0)));
    if (phase.contains("missing") && phase["missing"].is_number()) {
      out << " (" << phase["missing"].get<long long>() << " missing, "
          << phase["extra"].get<long long>() << " extra)";
    }
    out << "\n";
  }
}

// The model: its springs, the stiffness a simulator gets, E on the named cases.
void PrintModel(const proto::Json& r, std::ostream& out) {
  out << "springs:           " << r.value("springs", proto::Json::array()).size() << " of "
      << r.value("genes", 0) << " genes";
  const int unseen = r.contains("outcome") ? r["outcome"].value("unseen_springs", 0) : 0;
  if (unseen > 0)
    out << " (+" << unseen << " between held nodes: "
        << proto::HeldSpringsText(r.contains("baseline") && r["baseline"].is_object())
        << ", proto/MODEL.md)";
  out << "\n";
  // The stiffness a simulator will get (proto/MODEL.md, "Simulator facts"): its range, and
  // the dead springs an export flags or drops, where the result identifies stiffness.
  if (r.value("identify", "") == "topology_and_stiffness" && r.contains("stiffness") &&
      r["stiffness"].is_array() && !r["stiffness"].empty()) {
    const std::vector<double> k = r["stiffness"].get<std::vector<double>>();
    const io::StiffnessSpread spread = io::SpreadOf(k);
    const double fraction = io::ModelOptions{}.dead_fraction;
    const std::string unit = r.contains("units") && r["units"].is_object()
                                 ? " " + r["units"].value("stiffness", std::string())
                                 : std::string();
    out << "stiffness:         " << fmt::format("{:.4g}", spread.min) << " to "
        << fmt::format("{:.4g}", spread.max) << ", median " << fmt::format("{:.4g}", spread.median)
        << unit << " (spread "
        << fmt::format("{:.3g}", spread.min > 0.0 ? spread.max / spread.min : 0.0) << "); "
        << spread.below(k, fraction) << " dead (below " << fmt::format("{:g}", fraction)
        << " x the median: export flags them, --drop-dead leaves them out)\n";
  }
  // E is the one quality measure shown (the normalised error and the cost are in --json).
  // (A linear response: E is the small-load limit's, and the outcome has E as simulated.)
  const proto::Json outcome = r.value("outcome", proto::Json::object());
  const bool simulated = outcome.is_object() && outcome.contains("simulated_rms_error");
  out << "E (RMS nodal):     "
      << (r.contains("rms_error") ? fmt::format("{:.6g}", r["rms_error"].get<double>())
                                  : std::string("- (no equilibrium)"))
      << " on the named load cases (relative RMS nodal error against the reference"
      << (simulated ? ", small-load limit: rest-linear springs" : "") << ")"
      << (r.value("mechanism", false) ? "; a mechanism" : "") << "\n";
  if (simulated)
    out << "  as simulated:    " << ShortNumber(outcome["simulated_rms_error"])
        << " on the named load cases with nonlinear springs at their own size (as a simulator "
           "runs them); baseline "
        << ShortNumber(outcome.value("baseline_simulated_rms_error", proto::Json())) << "\n";
}

// Strategy continuous: the sparsity path, the regularisation, the held-out error.
void PrintContinuous(const proto::Json& r, std::ostream& out) {
  const proto::Json& c = r["continuous"];
  const proto::Json& path = c["path"];
  if (!path.empty()) {
    const auto error = [](const proto::Json& point) {
      return point.contains("rms_error") && point["rms_error"].is_number()
                 ? fmt::format("{:.4g}", point["rms_error"].get<double>())
                 : std::string("-");
    };
    out << "sparsity path:     " << path.size() << " points, from "
        << path.front().value("springs", 0) << " springs (E " << error(path.front()) << ") to "
        << path.back().value("springs", 0) << " (E " << error(path.back())
        << "); springfit plot --tradeoff draws it\n";
  }
  const proto::Json reg = c.value("regularization", proto::Json::object());
  const proto::Json tried = reg.value("tried", proto::Json::array());
  if (reg.value("strength", 0.0) > 0.0 || !tried.empty()) {
    out << "regularization:    " << fmt::format("{:.3g}", reg.value("strength", 0.0));
    if (!tried.empty()) {
      out << ", the lowest held-out E of those tried (";
      for (std::size_t i = 0; i < tried.size(); ++i) {
        const proto::Json& t = tried[i];
        out << (i > 0 ? ", " : "") << fmt::format("{:.3g}", t.value("strength", 0.0)) << ": "
            << (t["held_out_rms_error"].is_number()
                    ? fmt::format("{:.4g}", t["held_out_rms_error"].get<double>())
                    : std::string("-"));
      }
      out << ")";
    }
    out << "\n";
  }
  if (c.contains("held_out_rms_error") && c["held_out_rms_error"].is_number()) {
    out << "held-out E:        " << fmt::format("{:.6g}", c["held_out_rms_error"].get<double>())
        << " (each load case predicted by the springs fitted to the others)\n";
    // The case predicted worst (unpredictable: no equilibrium), beside its E when fitted:
    // the kind of deformation the other cases tell least about.
    const proto::Json per_case = c.value("held_out_rms_error_per_case", proto::Json::array());
    const proto::Json cases = r.value("load_cases", proto::Json::array());
    std::size_t worst = per_case.size();
    for (std::size_t k = 0; k < per_case.size() && k < cases.size(); ++k) {
      if (worst < per_case.size() && !per_case[worst].is_number()) break;
      if (!per_case[k].is_number() ||
          (worst == per_case.size() || per_case[k].get<double>() > per_case[worst].get<double>()))
        worst = k;
    }
    if (worst < per_case.size() && per_case.size() > 1) {
      const proto::Json& lc = cases[worst];
      out << "  worst predicted: '" << lc.value("name", std::string()) << "', E "
          << (per_case[worst].is_number() ? fmt::format("{:.4g}", per_case[worst].get<double>())
                                          : std::string("- (no equilibrium)"))
          << " (" << fmt::format("{:.4g}", std::sqrt(lc.value("normalized_error", 0.0)))
          << " fitted with it): the other cases tell least about its deformation\n";
    }
  }
}

// The closed-form baseline of an FEM reference, and a warning when the model is worse.
void PrintBaseline(const proto::Json& b, std::ostream& out) {
  out << "baseline:          " << b.value("recipe", std::string()) << " on the "
      << b.value("springs", 0) << " mesh edges: ";
  if (b.value("converged", false)) {
    out << "E " << fmt::format("{:.6g}", b.value("rms_error", 0.0)) << "\n";
  } else {
    out << "no equilibrium\n";
  }
  if (b.value("worse_than_baseline", false)) {
    out << "WARNING:           THIS MODEL IS WORSE THAN THE CLOSED-FORM BASELINE ("
        << b.value("recipe", std::string())
        << "): its stiffness on the mesh edges reproduces the reference better\n";
  }
}

// The certificate: unseen loads, by family, at amplitudes, and the eigenvalue bound.
void PrintGeneralization(const proto::Json& g, std::ostream& out) {
  // ("inf": some probe finds a mode the model leaves free; "-": not measured.)
  const auto number = [](const proto::Json& j, const char* key) {
    return ShortNumber(j.contains(key) ? j[key] : proto::Json());
  };
  const proto::Json held = g.value("held_out", proto::Json::object());
  const proto::Json base = g.value("baseline_held_out", proto::Json::object());
  const proto::Json probes = g.value("probes", proto::Json::object());
  out << "unseen loads:      " << held.value("probes", 0) << " held-out probes on "
      << probes.value("supports", 0) << " supports, never fitted (small-load limit): median E "
      << number(held, "median") << ", 95% " << number(held, "p95") << "; baseline "
      << number(base, "median") << ", 95% " << number(base, "p95") << "\n";
  const proto::Json families = g.value("by_family", proto::Json::object());
  const proto::Json base_families = g.value("baseline_by_family", proto::Json::object());
  out << "  by family:       ";
  bool first = true;
  for (const auto& [name, f] : families.items()) {
    out << (first ? "" : "; ") << name << " " << number(f, "median") << " (baseline "
        << number(base_families.value(name, proto::Json::object()), "median") << ")";
    first = false;
  }
  out << " (median E; named: the user's cases, fitted)\n";
  // The same loads at fractions of the load range, every model's springs nonlinear (as the
  // simulator runs them), whatever the fit's response.
  for (const auto& a : g.value("amplitudes", proto::Json::array())) {
    const proto::Json model = a.value("model", proto::Json::object());
    const proto::Json baseline = a.value("baseline", proto::Json::object());
    out << "  nonlinear at " << fmt::format("{:3.0f}", 100.0 * a.value("amplitude", 0.0))
        << "%: " << model.value("probes", 0) << " probes solved to equilibrium: median E "
        << number(model, "median") << ", 95% " << number(model, "p95") << "; baseline "
        << number(baseline, "median") << ", 95% " << number(baseline, "p95");
    if (a.value("reference_failed", 0) > 0)
      out << " (" << a.value("reference_failed", 0) << " left out: no reference equilibrium)";
    // (A model that turns a mesh element inside out under a probe fails it, whatever its E.)
    if (a.value("model_inverted", 0) > 0 || a.value("baseline_inverted", 0) > 0)
      out << "; inverting an element: " << a.value("model_inverted", 0) << " (baseline "
          << a.value("baseline_inverted", 0) << ")";
    out << "\n";
  }
  // Tool loads: a node (push) or three (grasp) moved in to a depth; the shape's E and the force
  // the tool feels.
  for (const auto& t : g.value("tool_pushes", proto::Json::array())) {
    const proto::Json model = t.value("model", proto::Json::object());
    const proto::Json baseline = t.value("baseline", proto::Json::object());
    const proto::Json model_force = t.value("model_force", proto::Json::object());
    const proto::Json baseline_force = t.value("baseline_force", proto::Json::object());
    out << "  tool push " << fmt::format("{:3.0f}", 100.0 * t.value("amplitude", 0.0))
        << "%: " << t.value("pushes", 0) << " pushes and " << t.value("grasps", 0)
        << " grasps (3 nodes) in by " << number(t, "depth") << ": median E "
        << number(model, "median") << ", tool force error " << number(model_force, "median")
        << " (force " << number(t, "model_force_ratio") << " of the reference's); baseline E "
        << number(baseline, "median") << ", force error " << number(baseline_force, "median")
        << " (" << number(t, "baseline_force_ratio") << ")";
    if (t.value("reference_failed", 0) > 0)
      out << " (" << t.value("reference_failed", 0) << " left out: no reference equilibrium)";
    if (t.value("model_inverted", 0) > 0 || t.value("baseline_inverted", 0) > 0)
      out << "; inverting an element: " << t.value("model_inverted", 0) << " (baseline "
          << t.value("baseline_inverted", 0) << ")";
    out << "\n";
  }
  // The bound in words a user can act on, beside the baseline's (issue 47 item 2).
  const proto::Json pencil_base = g.value("baseline_pencil", proto::Json::object());
  out << "  every load:      any load on your supports is reproduced within " << number(g, "bound")
      << " of the response in the energy norm (baseline within " << number(pencil_base, "bound")
      << "); generalised eigenvalues of (K_model, K_ref) in [" << number(g, "lambda_min") << ", "
      << number(g, "lambda_max") << "] (baseline [" << number(pencil_base, "lambda_min") << ", "
      << number(pencil_base, "lambda_max") << "])";
  const double lambda_min = g.value("lambda_min", 0.0);
  if (lambda_min > 0.0)
    out << ": under the load that finds its softest mode, the model moves "
        << fmt::format("{:.3g}", 1.0 / lambda_min) << " times as far as the reference";
  else
    out << ": the model leaves a mode free";
  out << "\n";
  if (g.contains("free_body") && g["free_body"].is_object()) {
    const proto::Json& model = g["free_body"]["model"];
    const proto::Json& free_baseline = g["free_body"]["baseline"];
    out << "  any support:     on the free body (modulo rigid motions, which bounds every support) "
           "in ["
        << number(model, "lambda_min") << ", " << number(model, "lambda_max")
        << "]: energy-norm error at most " << number(model, "bound") << " (baseline "
        << number(free_baseline, "bound") << ")\n";
  }
  if (g.value("returned_baseline", false))
    out << "WARNING:           THE FITTED MODEL DID NO BETTER THAN THE CLOSED-FORM BASELINE ON "
           "THE CHOOSING PROBES: the baseline is returned\n";
}

// The reference topology, when it is known: recovered or not, and what differs.
void PrintReferenceTopology(const proto::Json& r, std::ostream& out) {
  if (r.contains("exact") && r["exact"].is_boolean()) {
    out << "reference:         " << (r["exact"].get<bool>() ? "recovered exactly" : "not recovered")
        << " (" << r["missing"].size() << " missing, " << r["extra"].size() << " extra)\n";
    PrintPairs(out, "missing", r["missing"]);
    PrintPairs(out, "extra", r["extra"]);
  } else {
    out << "reference:         topology unknown (a positions or FEM reference, or springs outside "
           "the candidates)\n";
  }
  if (r.contains("direct") && r["direct"].is_object()) {
    PrintPairs(out, "added so the model carries the loads (below the threshold, or unseen)",
               r["direct"].value("added_to_carry", proto::Json::array()));
  }
}

}  // namespace

void PrintResultSummary(const proto::Json& r, std::ostream& out) {
  const bool continuous = r.contains("continuous") && r["continuous"].is_object();
  PrintRun(r, continuous, out);
  PrintModel(r, out);
  if (continuous) PrintContinuous(r, out);
  if (r.contains("baseline") && r["baseline"].is_object()) PrintBaseline(r["baseline"], out);
  if (r.contains("generalization") && r["generalization"].is_object())
    PrintGeneralization(r["generalization"], out);
  PrintReferenceTopology(r, out);
}

void PrintResult(const proto::Json& result, bool as_json) {
  if (as_json) {
    std::cout << proto::DumpCompact(result) << std::endl;
  } else {
    PrintResultSummary(result, std::cout);
  }
}

void WriteResultFile(const std::string& path, const proto::Json& result, const proto::Json& scene) {
  proto::Json file = result;
  file["scene_definition"] = scene;
  std::ofstream out(path);
  out << file.dump(1) << "\n";
  out.close();
  if (!out) throw std::runtime_error("cannot write the result file " + path);
}

}  // namespace springfit::cli
