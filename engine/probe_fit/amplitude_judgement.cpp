#include "engine/probe_fit/amplitude_judgement.h"

#include <cmath>
#include <limits>
#include <memory>
#include <numeric>
#include <optional>

#include "engine/runtime/options_check.h"

namespace springfit::response {
namespace {

// Per amplitude, the model's and the baseline's errors summarised (NaN: the reference failed).
std::vector<AmplitudeErrors> SummariesByAmplitude(
    const std::vector<double>& amplitudes, const std::vector<std::vector<double>>& model_errors,
    const std::vector<std::vector<double>>& baseline_errors) {
  std::vector<AmplitudeErrors> out;
  for (std::size_t a = 0; a < amplitudes.size(); ++a) {
    AmplitudeErrors e;
    e.amplitude = amplitudes[a];
    e.model = Summarize(model_errors[a]);
    e.baseline = Summarize(baseline_errors[a]);
    for (double v : model_errors[a]) e.reference_failed += std::isnan(v) ? 1 : 0;
    out.push_back(e);
  }
  return out;
}

}  // namespace

void AmplitudeOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  CheckAmplitudes(check, amplitudes);
  check.Require(max_probes >= 1, "max_probes", max_probes, "value >= 1");
}

std::vector<AmplitudeErrors> JudgeAtAmplitudes(const Problem& problem, const ProbeBank& bank,
                                               const SpringModel& model,
                                               const SpringModel& baseline,
                                               const AmplitudeOptions& options,
                                               Interruption* interruption, WorkerPool* pool) {
  options.Validate();
  const Scene& scene = problem.scene();
  if (scene.reference.kind == Reference::Kind::kPositions) return {};
  const int d = problem.dimension();
  std::vector<int> all(bank.probes.size());
  std::iota(all.begin(), all.end(), 0);
  const std::vector<int> judged = EvenlySpread(all, options.max_probes);
  const std::size_t amplitudes = options.amplitudes.size();
  // Per judged probe and amplitude: E of the model and of the baseline (NaN: the reference
  // has none there).
  std::vector<std::vector<double>> model_errors(amplitudes, std::vector<double>(judged.size()));
  std::vector<std::vector<double>> baseline_errors = model_errors;
  // Per amplitude and judged probe: whether the model's (baseline's) equilibrium inverts an
  // element.
  std::vector<std::vector<char>> model_inverts(amplitudes, std::vector<char>(judged.size(), 0));
  std::vector<std::vector<char>> baseline_inverts = model_inverts;

  const ReferenceModel reference_model(problem);
  const SpringSolverInput model_input(scene, model), baseline_input(scene, baseline);

  const auto judge = [&](int slot) {
    if (interruption && interruption->Check()) throw Interrupted();
    const auto i = static_cast<std::size_t>(slot);
    const Probe& probe = bank.probes[static_cast<std::size_t>(judged[i])];
    const FreeNodes free = FreeNodes::FromConstrained(
        bank.supports[static_cast<std::size_t>(probe.support)].constrained);
    ReferenceSolver reference_solver(reference_model.fem, reference_model.springs, free, problem,
                                     interruption);
    SpringResponse model_solver(model_input, free, LoadStepSolverOptions(problem), interruption);
    SpringResponse baseline_solver(baseline_input, free, LoadStepSolverOptions(problem),
                                   interruption);
    for (std::size_t a = 0; a < amplitudes; ++a) {
      const ScaledLoad load = ScaleLoad(probe.force, probe.prescribed, options.amplitudes[a]);
      const std::optional<Vector> reference =
          reference_solver.SolveAt(load, probe.reference, options.amplitudes[a]);
      if (!reference) {
        model_errors[a][i] = baseline_errors[a][i] = std::numeric_limits<double>::quiet_NaN();
        continue;
      }
      const auto error = [&](SpringResponse& solver, char& inverts) {
        const std::optional<Vector> u = solver.Solve(load.force, load.prescribed);
        if (!u) return std::numeric_limits<double>::infinity();
        inverts = InvertedElements(scene, *u) > 0 ? 1 : 0;
        return RelativeError(*u, *reference, free, d);
      };
      model_errors[a][i] = error(model_solver, model_inverts[a][i]);
      baseline_errors[a][i] = error(baseline_solver, baseline_inverts[a][i]);
    }
  };
  const int slots = static_cast<int>(judged.size());
  if (pool != nullptr && pool->threads() > 1) {
    // (While the pool works, the owner keeps polling: progress beats and stop requests go on.)
    pool->Run(slots, judge, [interruption] {
      if (interruption) interruption->Check();
    });
  } else {
    for (int slot = 0; slot < slots; ++slot) judge(slot);
  }
  std::vector<AmplitudeErrors> out =
      SummariesByAmplitude(options.amplitudes, model_errors, baseline_errors);
  for (std::size_t a = 0; a < amplitudes; ++a) {
    for (std::size_t i = 0; i < judged.size(); ++i) {
      out[a].model_inverted += model_inverts[a][i];
      out[a].baseline_inverted += baseline_inverts[a][i];
    }
  }
  return out;
}

}  // namespace springfit::response
