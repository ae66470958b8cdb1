#include "proto/search_codec.h"

#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "engine/api/input_error.h"
#include "engine/api/scene.h"
#include "proto/evaluation_codec.h"
#include "proto/names.h"
#include "proto/outcome_codec.h"
#include "proto/scene_codec.h"

namespace springfit::proto {
Json CountOrNull(int count) {
  return count < 0 ? Json(nullptr) : Json(count);
}

namespace {

Json TraceToJson(const std::vector<TraceRow>& trace) {
  Json rows = Json::array();
  for (const TraceRow& row : trace) rows.push_back(TraceRowToJson(row));
  return rows;
}

}  // namespace

// (The checkpoint's fingerprint hashes this text: its keys keep their order, an ordered_json's.)
Json SearchOptionsToJson(const SearchOptions& o) {
  Json j;
  j["population"] = o.population;
  j["max_generations"] = o.max_generations;
  j["max_seconds"] = o.max_seconds;
  j["stall_generations"] = o.stall_generations;
  j["target_normalized_error"] = o.target_normalized_error;
  j["max_springs"] = o.max_springs;
  j["target_error"] = o.target_error;
  j["max_spread"] = o.max_spread;
  j["load_size"] = o.load_size;
  j["regularization"] = o.choose_regularization ? Json("auto") : Json(o.regularization);
  j["probes"] = o.probes == SearchOptions::kAutomaticProbes ? Json("auto") : ProbesToJson(o.probes);
  j["selection"] = o.selection == SearchOptions::Selection::kRoulette ? "roulette" : "tournament";
  if (o.selection == SearchOptions::Selection::kTournament)
    j["tournament_size"] = o.tournament_size;
  if (o.selection == SearchOptions::Selection::kRoulette)
    j["roulette_exponent"] = o.roulette_exponent;
  j["crossover"] = o.crossover == SearchOptions::Crossover::kOnePoint ? "one_point" : "uniform";
  j["crossover_probability"] = o.crossover_probability;
  j["mutation_probability"] = o.mutation_probability;
  j["elites"] = o.elites;
  j["initial_density"] = {o.initial_density_low, o.initial_density_high};
  j["local_search"] = o.local_search;
  if (o.local_search) {
    j["local_search_batch"] = o.local_search_batch;
    j["local_search_combine"] = o.local_search_combine;
    j["local_search_swaps"] = o.local_search_swaps;
    if (o.local_search_swaps) j["swap_radius"] = o.swap_radius;
  }
  return j;
}

Json RunOptionsToJson(const SearchOptions& o, Strategy ran, bool fitted_to_probes) {
  Json j = SearchOptionsToJson(o);
  // What the strategy that ran does not read leaves; every strategy's run reads its time
  // limit, the spring budget, the error target and the load range (the verdict's).
  const bool genetic = ran == Strategy::kPaper || ran == Strategy::kHybrid;
  if (!genetic) {
    for (const char* key :
         {"population", "max_generations", "stall_generations", "selection", "tournament_size",
          "roulette_exponent", "crossover", "crossover_probability", "mutation_probability",
          "elites", "initial_density", "local_search", "local_search_batch", "local_search_combine",
          "local_search_swaps", "swap_radius"})
      j.erase(key);
  }
  if (!genetic && ran != Strategy::kDirect) j.erase("target_normalized_error");
  if (ran != Strategy::kContinuous) {
    for (const char* key : {"max_spread", "regularization", "probes"}) j.erase(key);
  } else if (fitted_to_probes && !o.choose_regularization && o.regularization == 0.0) {
    // On the probe fit a strength of 0 is none given: the continuation chooses it.
    j["regularization"] = "continuation";
  }
  return j;
}

Json TraceRowToJson(const TraceRow& r) {
  Json j;
  j["generation"] = r.generation;
  j["wall_seconds"] = r.wall_seconds;
  j["evaluations"] = r.evaluations;
  j["cache_hits"] = r.cache_hits;
  j["best_cost"] = r.best_cost;
  j["best_normalized_error"] = r.best_normalized_error;
  j["mean_cost"] = r.mean_cost;
  j["missing"] = CountOrNull(r.missing);
  j["extra"] = CountOrNull(r.extra);
  return j;
}

TraceRow TraceRowFromJson(const Json& j, const std::string& path) {
  // (Members it does not know, a newer writer's or a notification's own, are ignored.)
  auto at = [&](const char* key) -> const Json& { return RequiredMember(j, path, key); };
  auto count = [&](const char* key) {
    return at(key).is_null() ? -1 : ReadInt(at(key), JoinPath(path, key));
  };
  TraceRow r;
  r.generation = ReadInt(at("generation"), JoinPath(path, "generation"));
  r.wall_seconds = ReadNumber(at("wall_seconds"), JoinPath(path, "wall_seconds"));
  r.evaluations =
      static_cast<std::int64_t>(ReadUint64(at("evaluations"), JoinPath(path, "evaluations")));
  r.cache_hits =
      static_cast<std::int64_t>(ReadUint64(at("cache_hits"), JoinPath(path, "cache_hits")));
  r.best_cost = ReadNumber(at("best_cost"), JoinPath(path, "best_cost"));
  r.best_normalized_error =
      ReadNumber(at("best_normalized_error"), JoinPath(path, "best_normalized_error"));
  r.mean_cost = ReadNumber(at("mean_cost"), JoinPath(path, "mean_cost"));
  r.missing = count("missing");
  r.extra = count("extra");
  return r;
}

Json ProgressBeatToJson(const ProgressBeat& b) {
  Json j;
  j["phase"] = std::string(b.phase);
  j["wall_seconds"] = b.wall_seconds;
  j["generation"] = b.generation;
  j["evaluations"] = b.evaluations;
  j["best_normalized_error"] =
      std::isfinite(b.best_normalized_error) ? Json(b.best_normalized_error) : Json(nullptr);
  j["eta_seconds"] = std::isfinite(b.eta_seconds) ? Json(b.eta_seconds) : Json(nullptr);
  return j;
}

void ProgressBeatFromJson(const Json& j, const std::string& path, PhaseBeat& out) {
  auto at = [&](const char* key) -> const Json& { return RequiredMember(j, path, key); };
  out.phase = ReadString(at("phase"), JoinPath(path, "phase"));
  ProgressBeat& b = out.beat;
  b.phase = out.phase;
  b.wall_seconds = ReadNumber(at("wall_seconds"), JoinPath(path, "wall_seconds"));
  b.generation = ReadInt(at("generation"), JoinPath(path, "generation"));
  b.evaluations =
      static_cast<std::int64_t>(ReadUint64(at("evaluations"), JoinPath(path, "evaluations")));
  const Json& e = at("best_normalized_error");
  b.best_normalized_error = e.is_null() ? std::numeric_limits<double>::quiet_NaN()
                                        : ReadNumber(e, JoinPath(path, "best_normalized_error"));
  // (Absent from an older daemon's beats: no estimate.)
  if (const auto eta = j.find("eta_seconds"); eta != j.end() && !eta->is_null())
    b.eta_seconds = ReadNumber(*eta, JoinPath(path, "eta_seconds"));
}

Json IdentifiabilityToJson(const IdentifiabilityReport& report) {
  Json j;
  j["unseen"] = PairsToJson(report.unseen);
  j["analysed"] = report.groups_analysed;
  j["not_analysed"] = report.groups_analysed ? Json(nullptr) : Json(report.not_analysed);
  j["rank"] = report.groups_analysed ? Json(report.rank) : Json(nullptr);
  Json groups = Json::array();
  for (const DependentGroup& g : report.groups) {
    Json group;
    group["springs"] = PairsToJson(g.springs);
    group["dependencies"] = g.dependencies;
    group["suggestion"] = g.suggestion ? Json(g.suggestion->text) : Json(nullptr);
    groups.push_back(std::move(group));
  }
  j["groups"] = std::move(groups);
  return j;
}

namespace {

// Strategy direct's own fields: confidences and the details of its solve.
void DirectDetailsToJson(const Problem& problem, const DirectResult& d, Json& j) {
  // Confidence of each identified spring, and the absent ones closest to being present.
  Json confidence = nullptr;
  Json near = Json::array();
  if (!d.confidence.empty()) {
    confidence = Json::array();
    for (int g = 0; g < static_cast<int>(d.genome.size()); ++g) {
      const NodePair pair = problem.candidates().pairs[problem.gene_candidates()[g]];
      if (d.genome[g]) {
        confidence.push_back(NumberOrText(d.confidence[g]));
      } else if (std::isfinite(d.confidence[g]) && d.confidence[g] > -2.0) {
        near.push_back({{"spring", {pair.first, pair.second}},
                        {"weight", d.weights[g]},
                        {"confidence", d.confidence[g]}});
      }
    }
  }
  j["confidence"] = std::move(confidence);
  Json direct;
  direct["force_residual"] = d.force_residual;
  direct["nnls_residual"] = d.nnls_residual;
  direct["nnls_converged"] = d.nnls.converged;
  direct["nnls_pivots"] = d.nnls.iterations;
  direct["refined"] = d.refined;
  direct["refinement_iterations"] = d.refinement_iterations;
  direct["topology_threshold"] =
      d.topology_threshold > 0.0 ? Json(d.topology_threshold) : Json(nullptr);
  std::vector<NodePair> added;
  for (const int g : d.added_to_carry)
    added.push_back(problem.candidates().pairs[problem.gene_candidates()[g]]);
  direct["added_to_carry"] = PairsToJson(added);
  direct["displacement_only"] = d.displacement_only;
  direct["pinned_spring"] = nullptr;
  if (d.pinned_gene >= 0) {
    const NodePair pinned = problem.candidates().pairs[problem.gene_candidates()[d.pinned_gene]];
    direct["pinned_spring"] = {pinned.first, pinned.second};
  }
  std::vector<NodePair> unseen;
  for (const int g : d.unseen)
    unseen.push_back(problem.candidates().pairs[problem.gene_candidates()[g]]);
  direct["unseen"] = PairsToJson(unseen);
  direct["absent_near_threshold"] = std::move(near);
  direct["seconds"] = {{"assemble", d.assemble_seconds},
                       {"solve", d.solve_seconds},
                       {"evaluate", d.evaluate_seconds}};
  j["direct"] = std::move(direct);
}

// E = sqrt(e), or null where there is no equilibrium (e infinite).
Json RmsOrNull(double normalized_error) {
  return std::isfinite(normalized_error) ? Json(std::sqrt(normalized_error)) : Json(nullptr);
}

Json ContinuousDetailsToJson(const IdentificationResult::Continuous& c) {
  Json j;
  Json path = Json::array();
  for (const auto& point : c.path) {
    path.push_back({{"springs", point.springs},
                    {"normalized_error", point.normalized_error},
                    {"rms_error", RmsOrNull(point.normalized_error)}});
  }
  j["path"] = std::move(path);
  j["chosen"] = c.chosen >= 0 ? Json(c.chosen) : Json(nullptr);  // null: the start
  j["started_from"] = c.started_from_baseline ? "baseline" : "training_stiffness";
  j["start_rms_error"] = RmsOrNull(c.start_normalized_error);
  j["fit_rms_error"] = RmsOrNull(c.fit_normalized_error);
  j["rejected"] = c.rejected;
  j["model_seconds"] = c.model_seconds;
  j["steps"] = c.steps;
  j["solves"] = c.solves;
  j["held_out_rms_error"] =
      c.held_out_normalized_error ? RmsOrNull(*c.held_out_normalized_error) : Json(nullptr);
  Json per_case = Json::array();
  for (double e : c.held_out_per_case) per_case.push_back(RmsOrNull(e));
  j["held_out_rms_error_per_case"] = std::move(per_case);
  Json regularization;
  regularization["strength"] = c.regularization;
  Json tried = Json::array();
  for (std::size_t i = 0; i < c.regularization_strengths.size(); ++i) {
    tried.push_back({{"strength", c.regularization_strengths[i]},
                     {"held_out_rms_error", RmsOrNull(c.regularization_held_out[i])}});
  }
  regularization["chosen_by"] = tried.empty() ? "setting" : "held_out";
  regularization["tried"] = std::move(tried);
  j["regularization"] = std::move(regularization);
  return j;
}

// A finite number, or null (infinity: no equilibrium; NaN: nothing measured).
Json NumberOrNull(double v) {
  return std::isfinite(v) ? Json(v) : Json(nullptr);
}

// (Infinite where some probe finds a mode the model leaves free: the string "inf"; null where
// nothing was measured.)
Json ErrorSummaryToJson(const response::ErrorSummary& s) {
  const auto number = [](double v) { return std::isnan(v) ? Json(nullptr) : NumberOrText(v); };
  return {{"probes", s.probes},
          {"median", number(s.median)},
          {"p95", number(s.p95)},
          {"rms", number(s.rms)}};
}

Json FamiliesToJson(const std::vector<response::FamilyErrors>& families) {
  Json j = Json::object();
  for (const auto& f : families)
    j[response::ProbeFamilyName(f.family)] = ErrorSummaryToJson(f.errors);
  return j;
}

Json PencilToJson(const response::PencilExtremes& x) {
  return {{"lambda_min", x.lambda_min},
          {"lambda_max", x.lambda_max},
          {"bound", NumberOrNull(x.Bound())}};
}

Json GeneralizationToJson(const response::Generalization& g) {
  Json j;
  j["probes"] = {{"total", g.probes},      {"fitted", g.fitted},
                 {"choosing", g.choosing}, {"held_out", g.held_out},
                 {"supports", g.supports}, {"named_weight", g.named_weight}};
  j["held_out"] = ErrorSummaryToJson(g.model_held_out);
  j["baseline_held_out"] = ErrorSummaryToJson(g.baseline_held_out);
  j["by_family"] = FamiliesToJson(g.model);
  j["baseline_by_family"] = FamiliesToJson(g.baseline);
  j["lambda_min"] = g.lambda_min;
  j["lambda_max"] = g.lambda_max;
  j["bound"] = NumberOrNull(g.bound);
  j["baseline_pencil"] = PencilToJson(g.baseline_pencil);
  Json amplitudes = Json::array();
  for (const response::AmplitudeErrors& a : g.amplitudes)
    amplitudes.push_back({{"amplitude", a.amplitude},
                          {"model", ErrorSummaryToJson(a.model)},
                          {"baseline", ErrorSummaryToJson(a.baseline)},
                          {"reference_failed", a.reference_failed},
                          {"model_inverted", a.model_inverted},
                          {"baseline_inverted", a.baseline_inverted}});
  j["amplitudes"] = std::move(amplitudes);
  Json pushes = Json::array();
  for (const response::ToolPushErrors& t : g.tool_pushes)
    pushes.push_back({{"amplitude", t.amplitude},
                      {"depth", t.depth},
                      {"model", ErrorSummaryToJson(t.model)},
                      {"baseline", ErrorSummaryToJson(t.baseline)},
                      {"model_force", ErrorSummaryToJson(t.model_force)},
                      {"baseline_force", ErrorSummaryToJson(t.baseline_force)},
                      {"model_force_ratio", NumberOrNull(t.model_force_ratio)},
                      {"baseline_force_ratio", NumberOrNull(t.baseline_force_ratio)},
                      {"pushes", t.pushes},
                      {"grasps", t.grasps},
                      {"reference_failed", t.reference_failed},
                      {"model_inverted", t.model_inverted},
                      {"baseline_inverted", t.baseline_inverted}});
  j["tool_pushes"] = std::move(pushes);
  Json pencils = Json::array();
  for (const auto& p : g.pencils)
    pencils.push_back({{"support", p.support},
                       {"model", PencilToJson(p.model)},
                       {"baseline", PencilToJson(p.baseline)}});
  j["supports"] = std::move(pencils);
  j["free_body"] = {{"model", PencilToJson(g.free_body)},
                    {"baseline", PencilToJson(g.baseline_free_body)}};
  j["fitted_to_probes"] = g.fitted_to_probes;
  j["returned_baseline"] = g.returned_baseline;
  if (g.returned_baseline) {
    j["baseline_choice"] = {
        {"fitted_choosing_rms_error", NumberOrNull(g.fitted_choosing_error)},
        {"baseline_choosing_rms_error", NumberOrNull(g.baseline_choosing_error)}};
  }
  if (g.fitted_to_probes) {
    Json fit;
    fit["method"] = g.fit.method;
    fit["regularization"] = g.fit.regularization;
    Json tried = Json::array();
    for (std::size_t i = 0; i < g.fit.regularizations.size(); ++i)
      tried.push_back({{"strength", g.fit.regularizations[i]},
                       {"choosing_rms_error", NumberOrNull(g.fit.regularization_select_errors[i])},
                       {"lambda_min", g.fit.regularization_lambda_min[i]}});
    fit["regularization_tried"] = std::move(tried);
    Json path = Json::array();
    for (const auto& p : g.fit.path)
      path.push_back({{"springs", p.springs},
                      {"choosing_rms_error", NumberOrNull(p.select_error)},
                      {"lambda_min", p.lambda_min}});
    fit["path"] = std::move(path);
    fit["chosen"] = g.fit.chosen;
    fit["gauss_newton_steps"] = g.fit.gauss_newton_accepted;
    Json modes = Json::array();
    for (const auto& m : g.fit.soft_mode_rounds)
      modes.push_back({{"probes", m.probes},
                       {"springs", m.springs},
                       {"choosing_rms_error", NumberOrNull(m.select_error)},
                       {"lambda_min", m.lambda_min},
                       {"lifted", m.lifted}});
    fit["soft_modes"] = std::move(modes);
    fit["soft_modes_chosen"] = g.fit.soft_mode_chosen;
    if (const auto& n = g.fit.nonlinear) {
      fit["nonlinear"] = {{"amplitudes", n->amplitudes},
                          {"fitted_cases", n->fitted_cases},
                          {"fitted_left_out", n->fitted_left_out},
                          {"left_for_memory", n->left_for_memory},
                          {"choosing_cases", n->choosing_cases},
                          {"start_choosing_rms_error", NumberOrNull(n->start_choosing_error)},
                          {"choosing_rms_error", NumberOrNull(n->choosing_error)},
                          {"baseline_choosing_rms_error", NumberOrNull(n->baseline_choosing_error)},
                          {"start_failed", n->start_failed},
                          {"failed", n->failed},
                          {"regularization", n->regularization},
                          {"gauss_newton_steps", n->steps},
                          {"seconds", n->seconds}};
      // (The bound is half the machine's memory: written only where it cut, so that the same
      // scene and seed write the same result on every machine it does not cut on.)
      if (n->left_for_memory > 0) {
        fit["nonlinear"]["case_bytes"] = n->case_bytes;
        fit["nonlinear"]["max_bytes"] = n->max_bytes;
      }
    }
    j["fit"] = std::move(fit);
  }
  return j;
}

// The closed-form baseline on the same cases, and whether the model is worse: no equilibrium
// where the baseline has one, or a larger error.
Json BaselineToJson(const BaselineReport& baseline, const Evaluation& model) {
  Json b;
  b["recipe"] = baseline.recipe;
  b["springs"] = baseline.springs;
  b["converged"] = baseline.converged;
  if (baseline.converged) {
    b["normalized_error"] = baseline.normalized_error;
    b["rms_error"] = baseline.rms_error;
  }
  const bool stable = model.converged && !model.mechanism;
  b["worse_than_baseline"] =
      baseline.converged && (!stable || model.normalized_error > baseline.normalized_error);
  return b;
}

// Strategy hybrid's direct phase: its time, error and distance to the reference topology.
Json DirectPhaseToJson(const IdentificationResult::DirectPhase& direct) {
  Json phase;
  phase["seconds"] = direct.seconds;
  phase["normalized_error"] = direct.normalized_error;
  const auto& difference = direct.difference;
  phase["missing"] = difference ? Json(difference->missing.size()) : Json(nullptr);
  phase["extra"] = difference ? Json(difference->extra.size()) : Json(nullptr);
  return phase;
}

}  // namespace

Json ResultToJson(const Problem& problem, const IdentificationResult& r, bool with_trace) {
  Json j;
  j["scene"] = problem.scene().name;
  j["strategy"] = StrategyName(r.options.strategy);
  j["ran"] = StrategyName(r.ran);
  j["identify"] = IdentifyName(r.options.identify);
  j["response"] = ResponseName(problem.response());
  j["seed"] = r.options.seed;
  j["stop"] = StopReasonName(r.stop);
  j["stop_message"] = r.stop_message;
  j["outcome"] = OutcomeToJson(r.outcome);
  // Notices about the scene (engine/api/problem.h, SceneNotices): shown wherever the result is.
  j["notices"] = SceneNotices(problem);
  // The units the numbers are in, as the scene states them (null: unstated).
  const auto& units = problem.scene().units;
  j["units"] = units ? UnitsToJson(DeriveUnits(*units)) : Json(nullptr);
  if (const auto exact = r.exact()) {
    j["exact"] = *exact;
    j["hamming"] = r.difference->hamming();
    j["missing"] = PairsToJson(r.difference->missing);
    j["extra"] = PairsToJson(r.difference->extra);
  } else {
    j["exact"] = nullptr;
    j["hamming"] = nullptr;
    j["missing"] = nullptr;
    j["extra"] = nullptr;
  }
  j["genes"] = problem.gene_count();
  j["springs"] = PairsToJson(r.springs);
  j["stiffness"] = r.stiffness;  // parallel to springs
  std::vector<NodePair> unidentifiable;
  for (int c : problem.unidentifiable()) unidentifiable.push_back(problem.candidates().pairs[c]);
  j["unidentifiable"] = PairsToJson(unidentifiable);
  j["identifiability"] = IdentifiabilityToJson(r.identifiability);
  const Json evaluation = EvaluationToJson(problem, r.evaluation);
  for (const auto& [key, value] : evaluation.items()) j[key] = value;
  // E, the relative RMS nodal error, where the model has equilibria (penalties are not errors).
  const bool stable = r.evaluation.converged && !r.evaluation.mechanism;
  if (stable) j["rms_error"] = std::sqrt(r.evaluation.normalized_error);
  if (r.baseline) j["baseline"] = BaselineToJson(*r.baseline, r.evaluation);
  j["generations"] = r.generations;
  j["best_generation"] = r.best_generation;
  j["evaluations"] = r.counters.evaluations;
  j["cache_hits"] = r.counters.cache_hits;
  j["wall_seconds"] = r.wall_seconds;
  j["options"] = RunOptionsToJson(r.options, r.ran, r.continuous && r.continuous->fitted_to_probes);
  if (r.direct_phase) j["direct_phase"] = DirectPhaseToJson(*r.direct_phase);
  if (r.direct) DirectDetailsToJson(problem, *r.direct, j);
  if (r.continuous) j["continuous"] = ContinuousDetailsToJson(*r.continuous);
  if (r.generalization) j["generalization"] = GeneralizationToJson(*r.generalization);
  if (with_trace) j["trace"] = TraceToJson(r.trace);
  return j;
}

std::string NonlinearFitNotes(const Json& nonlinear) {
  const auto count = [&nonlinear](const char* key) -> long long {
    return nonlinear.contains(key) && nonlinear[key].is_number_integer()
               ? nonlinear[key].get<long long>()
               : 0;
  };
  std::string notes;
  if (const long long out = count("fitted_left_out"); out > 0)
    notes += fmt::format(
        "; {} fitted equilibria left out (the rest-linear model folds there or has none)", out);
  if (const long long memory = count("left_for_memory"); memory > 0) {
    const double case_bytes = nonlinear.value("case_bytes", 0.0);
    const double max_bytes = nonlinear.value("max_bytes", 0.0);
    notes += fmt::format(
        "; {} fitted probes left out for memory ({:.1f} MB per equilibrium, {:.1f} GB allowed{})",
        memory, case_bytes / 1e6, max_bytes / 1e9,
        static_cast<double>(count("fitted_cases")) * case_bytes > max_bytes
            ? ": the named cases alone exceed it"
            : "");
  }
  if (const long long failed = count("failed"); failed > 0)
    notes += fmt::format("; {} choosing equilibria not found (a fold or no equilibrium)", failed);
  return notes;
}

std::string TraceCsvHeader() {
  return "generation,wall_seconds,evaluations,cache_hits,best_cost,best_normalized_error,mean_cost,"
         "missing,extra";
}

std::string TraceRowToCsv(const TraceRow& r) {
  auto count = [](int c) { return c < 0 ? std::string() : std::to_string(c); };
  const std::string numbers =
      fmt::format("{:.6f},{},{},{:.17g},{:.17g},{:.17g}", r.wall_seconds, r.evaluations,
                  r.cache_hits, r.best_cost, r.best_normalized_error, r.mean_cost);
  return std::to_string(r.generation) + "," + numbers + "," + count(r.missing) + "," +
         count(r.extra);
}

void ExpectResultOfScene(const StoredResult& result, const Problem& problem) {
  if (result.scene != problem.scene().name ||
      (result.genes && *result.genes != problem.gene_count())) {
    throw InputError("", "the result is of scene '" + result.scene + "' (" +
                             std::to_string(result.genes.value_or(-1)) +
                             " genes), the scene given is '" + problem.scene().name + "' (" +
                             std::to_string(problem.gene_count()) + " genes)");
  }
}

namespace {

// A result's node pairs are springs, which have no direction: each is read as (smaller, larger)
// node index, once here, so that every reader finds it among the engine's candidates as it is.
std::vector<NodePair> ReadSpringPairs(const Json& json, const std::string& path) {
  std::vector<NodePair> pairs = ReadNodePairs(json, path);
  for (NodePair& p : pairs) {
    if (p.first > p.second) std::swap(p.first, p.second);
  }
  return pairs;
}

// `continuous.path` and `continuous.chosen` of a result (proto/RUN.md).
void ReadContinuousPath(const Json& c, StoredResult& r) {
  if (c.contains("path")) {
    r.path = ReadArray<StoredResult::PathPoint>(
        c["path"], "continuous.path", [](const Json& p, const std::string& at) {
          ExpectObject(p, at);
          StoredResult::PathPoint point;
          point.springs = ReadInt(p.value("springs", Json()), at + ".springs");
          // (null where the point had no equilibrium: NaN, not drawn.)
          point.rms_error = p.contains("rms_error") && !p["rms_error"].is_null()
                                ? ReadNumber(p["rms_error"], at + ".rms_error")
                                : std::numeric_limits<double>::quiet_NaN();
          return point;
        });
  }
  if (c.contains("chosen") && !c["chosen"].is_null())
    r.chosen = ReadInt(c["chosen"], "continuous.chosen");
}

// What the load cases do not determine (`identifiability`): the unseen springs and those of the
// dependent groups, and whether (and why not) the groups were analysed.
void ReadIdentifiability(const Json& id, StoredResult& r) {
  if (id.contains("unseen"))
    r.undetermined = ReadSpringPairs(id["unseen"], "identifiability.unseen");
  if (id.contains("analysed")) {
    if (!id["analysed"].is_boolean())
      throw InputError("identifiability.analysed", "expected a boolean");
    r.groups_analysed = id["analysed"].get<bool>();
  }
  if (id.contains("not_analysed") && !id["not_analysed"].is_null()) {
    if (!id["not_analysed"].is_string())
      throw InputError("identifiability.not_analysed", "expected a string or null");
    r.groups_not_analysed = id["not_analysed"].get<std::string>();
  }
  if (id.contains("groups")) {
    const auto groups = ReadArray<std::vector<NodePair>>(
        id["groups"], "identifiability.groups", [](const Json& g, const std::string& at) {
          ExpectObject(g, at);
          return g.contains("springs") ? ReadSpringPairs(g["springs"], at + ".springs")
                                       : std::vector<NodePair>{};
        });
    for (const std::vector<NodePair>& springs : groups)
      r.undetermined.insert(r.undetermined.end(), springs.begin(), springs.end());
  }
}

}  // namespace

StoredResult StoredResultFromJson(const Json& json) {
  if (!json.is_object()) throw InputError("", "a result is a JSON object (proto/RUN.md)");
  for (const char* key : {"scene", "strategy", "stop", "springs"}) {
    if (!json.contains(key)) throw InputError(key, "required in a result (proto/RUN.md)");
  }
  StoredResult r;
  r.scene = ReadString(json["scene"], "scene");
  r.strategy = ReadString(json["strategy"], "strategy");
  r.stop = ReadString(json["stop"], "stop");
  if (json.contains("seed")) r.seed = ReadUint64(json["seed"], "seed");
  if (json.contains("genes")) r.genes = ReadInt(json["genes"], "genes");
  r.springs = ReadSpringPairs(json["springs"], "springs");
  if (json.contains("stiffness")) {
    const Json& k = json["stiffness"];
    ExpectArray(k, "stiffness");
    if (k.size() != r.springs.size())
      throw InputError("stiffness", "must have one value per spring of `springs`");
    for (std::size_t s = 0; s < k.size(); ++s)
      r.stiffness.push_back(ReadNumber(k[s], "stiffness[" + std::to_string(s) + "]"));
  }
  if (json.contains("trace")) {
    const Json& t = json["trace"];
    ExpectArray(t, "trace");
    r.trace.emplace();
    for (std::size_t i = 0; i < t.size(); ++i)
      r.trace->push_back(TraceRowFromJson(t[i], "trace[" + std::to_string(i) + "]"));
  }
  if (json.contains("continuous") && json["continuous"].is_object())
    ReadContinuousPath(json["continuous"], r);
  if (json.contains("rms_error")) r.rms_error = ReadNumber(json["rms_error"], "rms_error");
  if (json.contains("unidentifiable"))
    r.unidentifiable = ReadSpringPairs(json["unidentifiable"], "unidentifiable");
  if (json.contains("identifiability") && json["identifiability"].is_object())
    ReadIdentifiability(json["identifiability"], r);
  if (json.contains("baseline") && json["baseline"].is_object()) {
    const Json& b = json["baseline"];
    if (b.contains("rms_error"))
      r.baseline_rms_error = ReadNumber(b["rms_error"], "baseline.rms_error");
    if (b.contains("springs")) r.baseline_springs = ReadInt(b["springs"], "baseline.springs");
  }
  if (json.contains("outcome")) r.outcome = OutcomeFromJson(json["outcome"], "outcome");
  if (json.contains("generalization") && json["generalization"].is_object()) {
    const Json& g = json["generalization"];
    for (const auto& [key, value] :
         {std::pair{"lambda_min", &r.lambda_min}, std::pair{"lambda_max", &r.lambda_max}})
      if (g.contains(key) && g[key].is_number())
        *value = ReadNumber(g[key], std::string("generalization.") + key);
  }
  return r;
}

}  // namespace springfit::proto
