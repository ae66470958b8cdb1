#include "proto/outcome_codec.h"

#include <cmath>

#include "engine/api/input_error.h"

namespace springfit::proto {
namespace {

Json Optional(const std::optional<double>& v) {
  return v ? NumberOrText(*v) : Json(nullptr);
}

// A number that may be absent, null, or one of NumberOrText's non-finite spellings.
std::optional<double> ReadOptional(const Json& j, std::string_view key, const std::string& path) {
  if (!j.contains(key) || j[key].is_null()) return std::nullopt;
  const Json& v = j[key];
  if (v.is_string()) {
    const std::string text = v.get<std::string>();
    if (text == "inf") return HUGE_VAL;
    if (text == "-inf") return -HUGE_VAL;
    if (text == "nan") return std::nullopt;
  }
  return ReadNumber(v, JoinPath(path, key));
}

}  // namespace

Json OutcomeToJson(const Outcome& o) {
  Json j;
  j["verdict"] = VerdictName(o.verdict);
  j["headline"] = o.Headline();
  j["reason"] = o.reason;
  j["unmet"] = o.unmet;
  j["doubts"] = o.doubts;
  j["springs"] = o.springs;
  j["unseen_springs"] = o.unseen_springs;
  j["rms_error"] = Optional(o.rms_error);
  j["baseline_rms_error"] = Optional(o.baseline_rms_error);
  if (o.simulated_rms_error) {
    j["simulated_rms_error"] = Optional(o.simulated_rms_error);
    j["baseline_simulated_rms_error"] = Optional(o.baseline_simulated_rms_error);
  }
  if (o.held_out_rms_error || o.held_out_p95) {
    j["held_out"] = {{"of", o.held_out_of},
                     {"median", Optional(o.held_out_rms_error)},
                     {"p95", Optional(o.held_out_p95)},
                     {"baseline_median", Optional(o.baseline_held_out_rms_error)}};
  } else {
    j["held_out"] = nullptr;
  }
  return j;
}

Outcome OutcomeFromJson(const Json& j, const std::string& path) {
  ExpectObject(j, path);
  Outcome o;
  const std::string name =
      ReadString(RequiredMember(j, path, "verdict"), JoinPath(path, "verdict"));
  const std::optional<Verdict> verdict = ParseVerdict(name);
  if (!verdict)
    throw InputError(JoinPath(path, "verdict"),
                     "unknown verdict '" + name + "' (usable, unmet_request, unusable, doubtful)");
  o.verdict = *verdict;
  if (j.contains("reason")) o.reason = ReadString(j["reason"], JoinPath(path, "reason"));
  if (j.contains("unmet")) {
    ExpectArray(j["unmet"], JoinPath(path, "unmet"));
    for (std::size_t i = 0; i < j["unmet"].size(); ++i)
      o.unmet.push_back(ReadString(j["unmet"][i], IndexPath(JoinPath(path, "unmet"), i)));
  }
  if (j.contains("doubts")) {
    ExpectArray(j["doubts"], JoinPath(path, "doubts"));
    for (std::size_t i = 0; i < j["doubts"].size(); ++i)
      o.doubts.push_back(ReadString(j["doubts"][i], IndexPath(JoinPath(path, "doubts"), i)));
  }
  if (j.contains("springs")) o.springs = ReadInt(j["springs"], JoinPath(path, "springs"));
  if (j.contains("unseen_springs"))
    o.unseen_springs = ReadInt(j["unseen_springs"], JoinPath(path, "unseen_springs"));
  o.rms_error = ReadOptional(j, "rms_error", path);
  o.baseline_rms_error = ReadOptional(j, "baseline_rms_error", path);
  o.simulated_rms_error = ReadOptional(j, "simulated_rms_error", path);
  o.baseline_simulated_rms_error = ReadOptional(j, "baseline_simulated_rms_error", path);
  if (j.contains("held_out") && j["held_out"].is_object()) {
    const Json& h = j["held_out"];
    const std::string at = JoinPath(path, "held_out");
    if (h.contains("of")) o.held_out_of = ReadString(h["of"], JoinPath(at, "of"));
    o.held_out_rms_error = ReadOptional(h, "median", at);
    o.held_out_p95 = ReadOptional(h, "p95", at);
    o.baseline_held_out_rms_error = ReadOptional(h, "baseline_median", at);
  }
  return o;
}

std::string HeldSpringsText(bool fem) {
  return std::string("no load case sees them; exports add them at ") +
         (fem ? "the recipe's stiffness (the training stiffness where no mesh edge joins them)"
              : "the training stiffness");
}

}  // namespace springfit::proto
