#include "engine/response/amplitude_judgement.h"

#include <cmath>
#include <limits>
#include <memory>
#include <numeric>
#include <optional>

#include "engine/equilibrium.h"
#include "engine/fem/fem_equilibrium.h"
#include "engine/options_check.h"

namespace springfit::response {
namespace {

// The probes judged: at most `limit`, evenly spread over the bank's order (which runs support
// by support, family by family).
std::vector<int> JudgedProbes(const ProbeBank& bank, int limit) {
  std::vector<int> all(bank.probes.size());
  std::iota(all.begin(), all.end(), 0);
  if (static_cast<int>(all.size()) <= limit) return all;
  std::vector<int> some;
  for (int i = 0; i < limit; ++i)
    some.push_back(all[static_cast<std::size_t>(i) * all.size() / static_cast<std::size_t>(limit)]);
  return some;
}

// A spring model as an equilibrium solver's geometry and springs.
struct SpringSolverInput {
  SpringGeometry geometry;
  ActiveSprings springs;
  SpringSolverInput(const Scene& scene, const SpringModel& model)
      : geometry(scene.dimension, scene.rest, model.pairs) {
    for (std::size_t s = 0; s < model.pairs.size(); ++s) {
      springs.index.push_back(static_cast<int>(s));
      springs.stiffness.push_back(model.stiffness[s]);
    }
  }
};

SpringModel ReferenceSprings(const Scene& scene) {
  SpringModel m;
  m.pairs = scene.reference.springs;
  for (std::size_t s = 0; s < m.pairs.size(); ++s)
    m.stiffness.push_back(scene.reference.stiffness.size() == 1 ? scene.reference.stiffness[0]
                                                                : scene.reference.stiffness[s]);
  return m;
}

// A spring model's equilibria on one support, each amplitude warm-started from the last.
class SpringResponse {
 public:
  SpringResponse(const SpringSolverInput& input, const FreeNodes& free,
                 const EquilibriumOptions& options, Interruption* interruption)
      : input_(input), solver_(input.geometry, free, options) {
    solver_.set_interruption(interruption);
    held_ = solver_.RestMechanismModes(input.springs) == 0;
  }
  // The displacement under (force, prescribed), or nothing (a mechanism, no convergence).
  std::optional<Vector> Solve(const Vector& force, const Vector& prescribed) {
    if (!held_) return std::nullopt;
    if (last_.size() != force.size()) last_ = Vector::Zero(force.size());
    Vector u = last_;
    const EquilibriumSummary summary = solver_.Solve(input_.springs, force, prescribed, u);
    if (summary.termination == Termination::kInterrupted) throw Interrupted();
    if (!summary.converged()) {
      last_ = Vector::Zero(force.size());
      return std::nullopt;
    }
    last_ = u;
    return u;
  }

 private:
  const SpringSolverInput& input_;
  EquilibriumSolver solver_;
  bool held_ = false;
  Vector last_;
};

double RelativeError(const Vector& model, const Vector& reference, const FreeNodes& free, int d) {
  double error = 0.0, norm = 0.0;
  for (std::size_t node = 0; node < free.free_index.size(); ++node) {
    if (free.free_index[node] < 0) continue;
    const auto at = static_cast<Eigen::Index>(node) * d;
    error += (model.segment(at, d) - reference.segment(at, d)).squaredNorm();
    norm += reference.segment(at, d).squaredNorm();
  }
  return norm > 0.0 ? std::sqrt(error / norm) : std::numeric_limits<double>::quiet_NaN();
}

// The reference's response to a probe's loads on one support: the FEM model's nonlinear solve,
// or the reference MSS's. Checked for a stop at every Newton iteration too: a probe of a large
// nonlinear mesh is nine solves.
class ReferenceSolver {
 public:
  ReferenceSolver(const std::optional<fem::FemModel>& fem,
                  const std::optional<SpringSolverInput>& springs, const FreeNodes& free,
                  const Problem& problem, Interruption* interruption) {
    if (fem) {
      fem_.emplace(*fem, free);
      fem_->set_interruption(interruption);
    } else {
      springs_.emplace(*springs, free, problem.solver_options(), interruption);
    }
  }
  // nullopt where the reference has no equilibrium.
  std::optional<Vector> Solve(const Vector& force, const Vector& prescribed) {
    if (!fem_) return springs_->Solve(force, prescribed);
    Vector u = Vector::Zero(force.size());
    if (!fem_->Solve(force, prescribed, u).converged()) return std::nullopt;
    return u;
  }

 private:
  std::optional<fem::FemEquilibriumSolver> fem_;
  std::optional<SpringResponse> springs_;
};

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

SpringModel ModelOfWeights(const Problem& problem, const std::vector<double>& weights) {
  SpringModel m;
  const SpringGeometry& candidates = problem.candidates();
  for (std::size_t g = 0; g < weights.size(); ++g) {
    if (!(weights[g] > 0.0)) continue;
    m.pairs.push_back(candidates.pairs[static_cast<std::size_t>(problem.gene_candidates()[g])]);
    m.stiffness.push_back(weights[g]);
  }
  for (std::size_t u = 0; u < problem.unidentifiable().size(); ++u) {
    m.pairs.push_back(candidates.pairs[static_cast<std::size_t>(problem.unidentifiable()[u])]);
    m.stiffness.push_back(problem.unidentifiable_stiffness()[u]);
  }
  return m;
}

void AmplitudeOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  check.Require(!amplitudes.empty(), "amplitudes", 0.0, "at least one amplitude");
  for (std::size_t i = 0; i < amplitudes.size(); ++i) {
    check.Require(amplitudes[i] > 0.0 && amplitudes[i] <= 4.0, "amplitudes", amplitudes[i],
                  "every value in (0, 4]");
    if (i > 0)
      check.Require(amplitudes[i] > amplitudes[i - 1], "amplitudes", amplitudes[i], "ascending");
  }
  check.Require(max_probes >= 1, "max_probes", max_probes, "value >= 1");
}

std::vector<AmplitudeErrors> JudgeAtAmplitudes(const Problem& problem, const ProbeBank& bank,
                                               const SpringModel& model,
                                               const SpringModel& baseline,
                                               const AmplitudeOptions& options,
                                               Interruption* interruption, WorkerPool* pool) {
  options.Validate();
  const Scene& scene = problem.scene();
  if (problem.response() != Response::kNonlinear ||
      scene.reference.kind == Reference::Kind::kPositions)
    return {};
  const int d = problem.dimension();
  const std::vector<int> judged = JudgedProbes(bank, options.max_probes);
  const std::size_t amplitudes = options.amplitudes.size();
  // Per judged probe and amplitude: E of the model and of the baseline (NaN: the reference
  // has none there).
  std::vector<std::vector<double>> model_errors(amplitudes, std::vector<double>(judged.size()));
  std::vector<std::vector<double>> baseline_errors = model_errors;

  std::optional<fem::FemModel> fem;
  if (scene.reference.kind == Reference::Kind::kFem) fem = fem::FemModel::Build(scene);
  const SpringSolverInput model_input(scene, model), baseline_input(scene, baseline);
  std::optional<SpringSolverInput> reference_input;
  if (!fem) reference_input.emplace(scene, ReferenceSprings(scene));

  const auto judge = [&](int slot) {
    if (interruption && interruption->Check()) throw Interrupted();
    const auto i = static_cast<std::size_t>(slot);
    const Probe& probe = bank.probes[static_cast<std::size_t>(judged[i])];
    const FreeNodes free = FreeNodes::FromConstrained(
        bank.supports[static_cast<std::size_t>(probe.support)].constrained);
    ReferenceSolver reference_solver(fem, reference_input, free, problem, interruption);
    SpringResponse model_solver(model_input, free, problem.solver_options(), interruption);
    SpringResponse baseline_solver(baseline_input, free, problem.solver_options(), interruption);
    for (std::size_t a = 0; a < amplitudes; ++a) {
      const Vector force = options.amplitudes[a] * probe.force;
      const Vector prescribed = probe.prescribed.size() == 0
                                    ? Vector::Zero(force.size())
                                    : Vector(options.amplitudes[a] * probe.prescribed);
      const std::optional<Vector> reference = reference_solver.Solve(force, prescribed);
      if (!reference) {
        model_errors[a][i] = baseline_errors[a][i] = std::numeric_limits<double>::quiet_NaN();
        continue;
      }
      const auto error = [&](SpringResponse& solver) {
        const std::optional<Vector> u = solver.Solve(force, prescribed);
        return u ? RelativeError(*u, *reference, free, d) : std::numeric_limits<double>::infinity();
      };
      model_errors[a][i] = error(model_solver);
      baseline_errors[a][i] = error(baseline_solver);
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
  return SummariesByAmplitude(options.amplitudes, model_errors, baseline_errors);
}

}  // namespace springfit::response
