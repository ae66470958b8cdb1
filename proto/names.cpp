#include "proto/names.h"

#include "engine/api/input_error.h"

#include <cmath>
#include <stdexcept>

namespace springfit::proto {

std::string_view CandidateKindName(CandidateSpec::Kind kind) {
  switch (kind) {
    case CandidateSpec::Kind::kGrid:
      return "grid";
    case CandidateSpec::Kind::kNearest:
      return "nearest";
    case CandidateSpec::Kind::kRadius:
      return "radius";
    case CandidateSpec::Kind::kPairs:
      return "pairs";
    case CandidateSpec::Kind::kMesh:
      return "mesh";
  }
  return "?";
}

std::optional<CandidateSpec::Kind> ParseCandidateKind(std::string_view name) {
  for (auto k :
       {CandidateSpec::Kind::kGrid, CandidateSpec::Kind::kNearest, CandidateSpec::Kind::kRadius,
        CandidateSpec::Kind::kPairs, CandidateSpec::Kind::kMesh}) {
    if (CandidateKindName(k) == name) return k;
  }
  return std::nullopt;
}

std::string_view ReferenceKindName(Reference::Kind kind) {
  switch (kind) {
    case Reference::Kind::kMss:
      return "mss";
    case Reference::Kind::kPositions:
      return "positions";
    case Reference::Kind::kFem:
      return "fem";
  }
  return "?";
}

std::optional<Reference::Kind> ParseReferenceKind(std::string_view name) {
  for (auto k : {Reference::Kind::kMss, Reference::Kind::kPositions, Reference::Kind::kFem}) {
    if (ReferenceKindName(k) == name) return k;
  }
  return std::nullopt;
}

std::string_view MaterialModelName(MaterialModel model) {
  switch (model) {
    case MaterialModel::kLinear:
      return "linear";
    case MaterialModel::kStVenantKirchhoff:
      return "st_venant_kirchhoff";
    case MaterialModel::kNeoHookean:
      return "neo_hookean";
  }
  return "?";
}

std::optional<MaterialModel> ParseMaterialModel(std::string_view name) {
  for (auto m :
       {MaterialModel::kLinear, MaterialModel::kStVenantKirchhoff, MaterialModel::kNeoHookean}) {
    if (MaterialModelName(m) == name) return m;
  }
  return std::nullopt;
}

std::string_view PlaneModeName(PlaneMode mode) {
  return mode == PlaneMode::kStress ? "stress" : "strain";
}

std::optional<PlaneMode> ParsePlaneMode(std::string_view name) {
  if (name == "stress") return PlaneMode::kStress;
  if (name == "strain") return PlaneMode::kStrain;
  return std::nullopt;
}

std::string_view TerminationName(Termination termination) {
  switch (termination) {
    case Termination::kConverged:
      return "converged";
    case Termination::kNotConverged:
      return "not_converged";
    case Termination::kMechanism:
      return "mechanism";
    case Termination::kNotSolved:
      return "not_solved";
    case Termination::kInterrupted:
      return "interrupted";
  }
  return "?";
}

namespace {
constexpr Strategy kAllStrategies[] = {Strategy::kDefault, Strategy::kPaper, Strategy::kDirect,
                                       Strategy::kHybrid, Strategy::kContinuous};
}  // namespace

std::string_view StrategyName(Strategy strategy) {
  switch (strategy) {
    case Strategy::kDefault:
      return "default";
    case Strategy::kPaper:
      return "paper";
    case Strategy::kDirect:
      return "direct";
    case Strategy::kHybrid:
      return "hybrid";
    case Strategy::kContinuous:
      return "continuous";
  }
  return "?";
}

std::optional<Strategy> ParseStrategy(std::string_view name) {
  for (Strategy s : kAllStrategies) {
    if (StrategyName(s) == name) return s;
  }
  return std::nullopt;
}

Strategy StrategyFromName(const std::string& name, const std::string& path) {
  const auto strategy = ParseStrategy(name);
  if (!strategy)
    throw InputError(path, "unknown strategy '" + name + "' (expected " + StrategyNames() + ")");
  return *strategy;
}

std::string_view IdentifyName(Identify identify) {
  return identify == Identify::kTopology ? "topology" : "topology_and_stiffness";
}

std::string IdentifyNames() {
  return std::string(IdentifyName(Identify::kTopology)) + " or " +
         std::string(IdentifyName(Identify::kTopologyAndStiffness));
}

Identify IdentifyFromName(const std::string& name, const std::string& path) {
  for (Identify i : {Identify::kTopology, Identify::kTopologyAndStiffness}) {
    if (IdentifyName(i) == name) return i;
  }
  throw InputError(path, "unknown value '" + name + "' (expected " + IdentifyNames() + ")");
}

std::string_view ResponseName(Response response) {
  return response == Response::kLinear ? "linear" : "nonlinear";
}

Response ResponseFromName(const std::string& name, const std::string& path) {
  for (Response r : {Response::kLinear, Response::kNonlinear}) {
    if (ResponseName(r) == name) return r;
  }
  throw InputError(path, "unknown value '" + name + "' (expected linear or nonlinear)");
}

SearchSettings::Regularization RegularizationFromText(const std::string& text,
                                                      const std::string& path) {
  SearchSettings::Regularization r;
  if (text == "auto") {
    r.automatic = true;
    return r;
  }
  std::size_t used = 0;
  try {
    r.strength = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || !(r.strength >= 0.0 && std::isfinite(r.strength)))
    throw InputError(path, "must be \"auto\" or a finite number >= 0, got '" + text + "'");
  return r;
}

std::optional<int> ProbesFromText(const std::string& text, const std::string& path) {
  if (text == "auto") return std::nullopt;
  if (text == "none") return 0;
  const std::string rule = "must be \"auto\", \"none\" or a count from 1 to " +
                           std::to_string(SearchOptions::kMaxProbes) + ", got '" + text + "'";
  std::size_t used = 0;
  long count = 0;
  try {
    count = std::stol(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || count < 1 || count > SearchOptions::kMaxProbes)
    throw InputError(path, rule);
  return static_cast<int>(count);
}

Json ProbesToJson(int probes) {
  return probes == 0 ? Json("none") : Json(probes);
}

std::string_view StopReasonName(StopReason reason) {
  switch (reason) {
    case StopReason::kTargetReached:
      return "target_reached";
    case StopReason::kGenerationLimit:
      return "generation_limit";
    case StopReason::kTimeLimit:
      return "time_limit";
    case StopReason::kStalled:
      return "stalled";
    case StopReason::kCompleted:
      return "completed";
    case StopReason::kCancelled:
      return "cancelled";
    case StopReason::kMechanism:
      return "mechanism";
    case StopReason::kNoEquilibrium:
      return "no_equilibrium";
    case StopReason::kNotReproduced:
      return "not_reproduced";
  }
  return "?";
}

std::vector<Strategy> AllStrategies() {
  return {std::begin(kAllStrategies), std::end(kAllStrategies)};
}

std::string StrategyNames() {
  std::string out;
  for (std::size_t i = 0; i < std::size(kAllStrategies); ++i) {
    if (i > 0) out += i + 1 == std::size(kAllStrategies) ? " or " : ", ";
    out += StrategyName(kAllStrategies[i]);
  }
  return out;
}

}  // namespace springfit::proto
