#include "engine/identification/verdict.h"

#include <cmath>
#include <cstdio>

#include "engine/identification/identification_result.h"
#include "engine/number_text.h"

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

}  // namespace

std::string_view VerdictName(Verdict verdict) {
  switch (verdict) {
    case Verdict::kUsable:
      return "usable";
    case Verdict::kUnmetRequest:
      return "unmet_request";
    case Verdict::kUnusable:
      return "unusable";
  }
  return "unusable";
}

std::optional<Verdict> ParseVerdict(std::string_view name) {
  for (Verdict v : {Verdict::kUsable, Verdict::kUnmetRequest, Verdict::kUnusable})
    if (VerdictName(v) == name) return v;
  return std::nullopt;
}

std::string Outcome::Headline() const {
  std::string text =
      std::string(VerdictName(verdict)) + ": " + std::to_string(springs) + " springs";
  if (unseen_springs > 0)
    text += " (+" + std::to_string(unseen_springs) + " no load case sees, in exports)";
  text += ", E " + (rms_error ? NumberText(*rms_error) : std::string("-"));
  if (baseline_rms_error) text += " (baseline " + NumberText(*baseline_rms_error) + ")";
  if (held_out_rms_error) {
    text += ", unseen " + held_out_of + " E " + NumberText(*held_out_rms_error);
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
  o.verdict = o.unmet.empty() ? Verdict::kUsable : Verdict::kUnmetRequest;
  return o;
}

}  // namespace springfit
