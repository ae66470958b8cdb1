#include "engine/identification/verdict.h"

#include <cmath>

#include "engine/api/result.h"
#include "engine/problem/small_strain.h"
#include "engine/runtime/number_text.h"

namespace springfit {
namespace {

// Why the model is no answer, or empty: it is one (IdentificationResult::usable()), and no load
// on the user's supports finds a mode it leaves free.
std::string UnusableReason(const IdentificationResult& r) {
  const Evaluation& e = r.evaluation;
  if (e.mechanism)
    return "the model is a mechanism (" + std::to_string(e.mechanism_modes) +
           " free modes over the load cases): it cannot carry the loads";
  if (!e.converged) return "the model has no equilibrium under some load case";
  if (!(e.normalized_error < 1.0))
    return "E " + NumberText(std::sqrt(e.normalized_error)) +
           " on the load cases: the model predicts the reference no better than the rest shape";
  if (r.generalization && !std::isfinite(r.generalization->model_held_out.p95)) {
    if (!(r.generalization->lambda_min > 0.0))
      return "loads on the user's supports find a mode the model leaves free (lambda_min 0): "
             "it has no equilibrium under some held-out probe loads";
    return "held on other parts of its boundary, the model leaves a mode free that the "
           "reference holds: it has no equilibrium under some held-out probe loads";
  }
  return "";
}

// The hard requests of the options that the model does not meet, one line each.
std::vector<std::string> UnmetRequests(const IdentificationResult& r, const Outcome& o) {
  std::vector<std::string> unmet;
  const SearchOptions& options = r.options;
  if (options.max_springs > 0 && o.springs > options.max_springs)
    unmet.push_back("spring budget not met: " + std::to_string(o.springs) +
                    " springs, above max_springs " + std::to_string(options.max_springs) +
                    ": no model within the budget that carries every load was found (the "
                    "trade-off: springfit plot --tradeoff)");
  if (options.target_error > 0.0 && !(o.rms_error && *o.rms_error <= options.target_error))
    unmet.push_back("target error not met: E " +
                    (o.rms_error ? NumberText(*o.rms_error) : std::string("undefined")) +
                    ", above target_error " + NumberText(options.target_error));
  return unmet;
}

// A bound is doubted when it is worse than the recipe's by more than this factor: the bounds
// are worst cases from Lanczos extremes, and one a few percent above the recipe's (the plate:
// 2.02 against 1.99) says nothing a user can act on.
constexpr double kBoundMargin = 1.25;

// A model whose softest mode is this much softer than the reference (1/lambda_min times) is
// doubted when the recipe has no mode as soft: under the load that finds it, the model moves
// ten times more than the tissue.
constexpr double kSoftModeLambda = 0.1;

std::string Percent(double fraction) {
  return NumberText(100.0 * fraction) + "%";
}

// The certificate's doubts: on the user's supports (the bound, the softest mode), on loads the
// model was not fitted to, and on any support (the free body).
void CertificateDoubts(const response::Generalization& g, std::vector<std::string>& doubts) {
  const response::PencilExtremes& base = g.baseline_pencil;
  if (g.bound > kBoundMargin * base.Bound() && base.lambda_min > 0.0)
    doubts.push_back("the certificate: a load on your supports can move the model by up to " +
                     NumberText(g.bound) +
                     " times the reference's response in error (energy norm), the "
                     "closed-form recipe by at most " +
                     NumberText(base.Bound()) + " (generalised eigenvalues [" +
                     NumberText(g.lambda_min) + ", " + NumberText(g.lambda_max) +
                     "], the recipe's [" + NumberText(base.lambda_min) + ", " +
                     NumberText(base.lambda_max) +
                     "]): some load there finds a mode the model holds worse "
                     "than the recipe does");
  if (g.lambda_min > 0.0 && g.lambda_min < kSoftModeLambda && g.lambda_min < base.lambda_min)
    doubts.push_back(
        "a soft mode: under the load that finds it on your supports, the model "
        "moves " +
        NumberText(1.0 / g.lambda_min) +
        " times as far as the reference (the recipe's softest mode: " +
        NumberText(1.0 / base.lambda_min) + " times)");
  if (g.model_held_out.p95 > g.baseline_held_out.median)
    doubts.push_back("unseen loads: one in twenty of the held-out probes has E at or above " +
                     NumberText(g.model_held_out.p95) + ", above the recipe's median " +
                     NumberText(g.baseline_held_out.median));
  // Family by family: a kind of load (a tool's push, a grasp, a patch) the model meets worse
  // than the recipe, although the pooled median hides it (a 3D box: pushes 0.34 against the
  // recipe's 0.18, every other family better). The named cases are the fit's own: E says them.
  std::string families;
  for (const response::FamilyErrors& m : g.model) {
    if (m.family == response::ProbeFamily::kNamed) continue;
    for (const response::FamilyErrors& b : g.baseline)
      if (b.family == m.family && m.errors.median > b.errors.median)
        families += (families.empty() ? "" : ", ") +
                    std::string(response::ProbeFamilyName(m.family)) + " " +
                    NumberText(m.errors.median) + " (recipe " + NumberText(b.errors.median) + ")";
  }
  if (!families.empty())
    doubts.push_back("unseen loads of a kind: the model's median E is above the recipe's on " +
                     families);
  const double free_body = g.free_body.Bound();
  const double base_free_body = g.baseline_free_body.Bound();
  if (free_body > kBoundMargin * base_free_body && std::isfinite(base_free_body))
    doubts.push_back(
        "held by supports other than yours (the free body's bound, which covers "
        "every support): error up to " +
        NumberText(free_body) + " times the response, the recipe's " + NumberText(base_free_body));
}

// The judgement as the simulator runs it: nonlinear springs at the load range's sizes, and a
// tool's pushes (displacement and reaction force), beside the recipe.
void AsSimulatedDoubts(const response::Generalization& g, std::vector<std::string>& doubts) {
  std::string worse;
  int inverted = 0, base_inverted = 0;
  for (const response::AmplitudeErrors& a : g.amplitudes) {
    if (a.model.median > a.baseline.median)
      worse += (worse.empty() ? "" : ", ") + Percent(a.amplitude) + ": E " +
               NumberText(a.model.median) + " (recipe " + NumberText(a.baseline.median) + ")";
    inverted += a.model_inverted;
    base_inverted += a.baseline_inverted;
  }
  if (!worse.empty())
    doubts.push_back(
        "as the simulator runs it (nonlinear springs), the model is worse than the "
        "closed-form recipe at " +
        worse + " of the named loads' size");
  std::string pushes;
  for (const response::ToolPushErrors& t : g.tool_pushes) {
    if (t.model.median > t.baseline.median || t.model_force.median > t.baseline_force.median)
      pushes += (pushes.empty() ? "" : ", ") + Percent(t.amplitude) + ": E " +
                NumberText(t.model.median) + ", tool force error " +
                NumberText(t.model_force.median) + " (recipe " + NumberText(t.baseline.median) +
                ", " + NumberText(t.baseline_force.median) + ")";
    inverted += t.model_inverted;
    base_inverted += t.baseline_inverted;
  }
  if (!pushes.empty())
    doubts.push_back(
        "a tool's push (an imposed displacement) meets a model worse than the "
        "recipe at " +
        pushes);
  if (inverted > base_inverted)
    doubts.push_back("the model turns a mesh element inside out under " + std::to_string(inverted) +
                     " of the judged loads (the recipe under " + std::to_string(base_inverted) +
                     "): it folds where the tissue does not");
}

// Each doubt about a usable model, one line each.
std::vector<std::string> Doubts(const Problem& problem, const IdentificationResult& r) {
  std::vector<std::string> doubts;
  if (r.generalization) {
    CertificateDoubts(*r.generalization, doubts);
    AsSimulatedDoubts(*r.generalization, doubts);
  }
  if (r.as_simulated && r.as_simulated->baseline_rms_error &&
      r.as_simulated->rms_error > *r.as_simulated->baseline_rms_error)
    doubts.push_back(
        "as the simulator runs it (nonlinear springs), the model meets the named "
        "cases worse than the closed-form recipe: E " +
        NumberText(r.as_simulated->rms_error) + " (recipe " +
        NumberText(*r.as_simulated->baseline_rms_error) +
        "; in the small-load limit the fit judged by, " +
        NumberText(std::sqrt(r.evaluation.normalized_error)) + " and " +
        (r.baseline ? NumberText(r.baseline->rms_error) : std::string("-")) + ")");
  if (const auto strain = SmallStrainWarning(problem, r.options.load_size))
    doubts.push_back(*strain);
  return doubts;
}

}  // namespace

std::string_view VerdictName(Verdict verdict) {
  switch (verdict) {
    case Verdict::kUsable:
      return "usable";
    case Verdict::kUnmetRequest:
      return "unmet_request";
    case Verdict::kUnusable:
      return "unusable";
    case Verdict::kDoubtful:
      return "doubtful";
  }
  return "unusable";
}

std::optional<Verdict> ParseVerdict(std::string_view name) {
  for (Verdict v :
       {Verdict::kUsable, Verdict::kUnmetRequest, Verdict::kUnusable, Verdict::kDoubtful})
    if (VerdictName(v) == name) return v;
  return std::nullopt;
}

std::string Outcome::WhatToTry() const {
  if (verdict != Verdict::kDoubtful) return "";
  return "proto/RUN.md, \"What to try\": what changes each doubt, and what it costs";
}

std::string Outcome::Headline() const {
  std::string text =
      std::string(VerdictName(verdict)) + ": " + std::to_string(springs) + " springs";
  if (unseen_springs > 0)
    text += " (+" + std::to_string(unseen_springs) + " between held nodes, in exports)";
  // (A linear response: what the simulator shows first, the small-load limit beside it.)
  if (simulated_rms_error) {
    text += ", E " + NumberText(*simulated_rms_error) + " as simulated";
    if (baseline_simulated_rms_error)
      text += " (baseline " + NumberText(*baseline_simulated_rms_error) + ")";
    text += ", " + (rms_error ? NumberText(*rms_error) : std::string("-")) + " small-load";
  } else {
    text += ", E " + (rms_error ? NumberText(*rms_error) : std::string("-"));
  }
  if (baseline_rms_error) text += " (baseline " + NumberText(*baseline_rms_error) + ")";
  if (held_out_rms_error) {
    text += ", held-out " + held_out_of + " E " + NumberText(*held_out_rms_error);
    if (baseline_held_out_rms_error)
      text += " (baseline " + NumberText(*baseline_held_out_rms_error) + ")";
  }
  return text;
}

Outcome JudgeResult(const Problem& problem, const IdentificationResult& r) {
  Outcome o;
  o.springs = static_cast<int>(r.springs.size());
  o.unseen_springs = static_cast<int>(problem.unidentifiable().size());
  if (r.evaluation.converged && !r.evaluation.mechanism)
    o.rms_error = std::sqrt(r.evaluation.normalized_error);
  if (r.baseline && r.baseline->converged) o.baseline_rms_error = r.baseline->rms_error;
  if (r.as_simulated) {
    o.simulated_rms_error = r.as_simulated->rms_error;
    o.baseline_simulated_rms_error = r.as_simulated->baseline_rms_error;
  }
  if (r.generalization) {
    const response::Generalization& g = *r.generalization;
    o.held_out_of = "probes";
    if (!std::isnan(g.model_held_out.median)) o.held_out_rms_error = g.model_held_out.median;
    if (!std::isnan(g.model_held_out.p95)) o.held_out_p95 = g.model_held_out.p95;
    if (!std::isnan(g.baseline_held_out.median))
      o.baseline_held_out_rms_error = g.baseline_held_out.median;
  } else if (r.continuous && r.continuous->held_out_normalized_error) {
    o.held_out_of = "cases";
    o.held_out_rms_error = std::sqrt(*r.continuous->held_out_normalized_error);
  }
  o.reason = UnusableReason(r);
  if (!o.reason.empty()) {
    o.verdict = Verdict::kUnusable;
    return o;
  }
  o.unmet = UnmetRequests(r, o);
  o.doubts = Doubts(problem, r);
  o.verdict = !o.unmet.empty()    ? Verdict::kUnmetRequest
              : !o.doubts.empty() ? Verdict::kDoubtful
                                  : Verdict::kUsable;
  return o;
}

}  // namespace springfit
