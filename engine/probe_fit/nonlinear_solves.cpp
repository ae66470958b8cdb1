#include "engine/probe_fit/nonlinear_solves.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace springfit::response {

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

SpringModel ReferenceSprings(const Scene& scene) {
  SpringModel m;
  m.pairs = scene.reference.springs;
  for (std::size_t s = 0; s < m.pairs.size(); ++s)
    m.stiffness.push_back(scene.reference.stiffness.size() == 1 ? scene.reference.stiffness[0]
                                                                : scene.reference.stiffness[s]);
  return m;
}

SpringSolverInput::SpringSolverInput(const Scene& scene, const SpringModel& model)
    : geometry(scene.dimension, scene.rest, model.pairs) {
  for (std::size_t s = 0; s < model.pairs.size(); ++s) {
    springs.index.push_back(static_cast<int>(s));
    springs.stiffness.push_back(model.stiffness[s]);
  }
}

SpringResponse::SpringResponse(const SpringSolverInput& input, const FreeNodes& free,
                               const EquilibriumOptions& options, Interruption* interruption)
    : input_(input), solver_(input.geometry, free, options) {
  solver_.set_interruption(interruption);
  held_ = solver_.RestMechanismModes(input.springs) == 0;
}

std::optional<Vector> SpringResponse::Solve(const Vector& force, const Vector& prescribed) {
  if (!held_) return std::nullopt;
  const double size = std::sqrt(force.squaredNorm() + prescribed.squaredNorm());
  Vector u = last_.size() == force.size() && last_size_ > 0.0 ? Vector(size / last_size_ * last_)
                                                              : Vector::Zero(force.size());
  const EquilibriumSummary summary = solver_.Solve(input_.springs, force, prescribed, u, &solver_);
  last_summary_ = summary;
  if (summary.termination == Termination::kInterrupted) throw Interrupted();
  if (!summary.converged()) {
    last_.resize(0);
    last_size_ = 0.0;
    return std::nullopt;
  }
  last_ = u;
  last_size_ = size;
  return u;
}

EquilibriumOptions LoadStepSolverOptions(const Problem& problem) {
  EquilibriumOptions options = problem.solver_options();
  options.chord_contraction = kLoadStepChordContraction;
  options.response = Response::kNonlinear;
  return options;
}

ReferenceSolver::ReferenceSolver(const std::optional<fem::FemModel>& fem,
                                 const std::optional<SpringSolverInput>& springs,
                                 const FreeNodes& free, const Problem& problem,
                                 Interruption* interruption)
    : free_(free), interruption_(interruption) {
  if (fem) {
    fem_model_ = &*fem;
    const std::vector<Material>& materials = problem.scene().reference.fem.materials;
    linear_ = std::all_of(materials.begin(), materials.end(),
                          [](const Material& m) { return m.model == MaterialModel::kLinear; });
  } else {
    springs_.emplace(*springs, free, problem.solver_options(), interruption);
  }
}

std::optional<Vector> ReferenceSolver::Solve(const Vector& force, const Vector& prescribed) {
  if (!fem_model_) return springs_->Solve(force, prescribed);
  if (!fem_) {
    fem_.emplace(*fem_model_, free_);
    fem_->set_interruption(interruption_);
  }
  Vector u = Vector::Zero(force.size());
  if (!fem_->Solve(force, prescribed, u).converged()) return std::nullopt;
  return u;
}

std::optional<Vector> ReferenceSolver::SolveAt(const ScaledLoad& load, const Vector& at_size,
                                               double amplitude) {
  if (linear_) return Vector(amplitude * at_size);
  return Solve(load.force, load.prescribed);
}

ReferenceModel::ReferenceModel(const Problem& problem) {
  const Scene& scene = problem.scene();
  if (scene.reference.kind == Reference::Kind::kFem)
    fem = fem::FemModel::Build(scene);
  else
    springs.emplace(scene, ReferenceSprings(scene));
}

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

namespace {

// The signed volume (area) of the simplex `nodes` at positions x, times d!.
double SignedVolume(const std::vector<int>& nodes, const Vector& x, int d) {
  Matrix edges(d, d);
  for (int a = 0; a < d; ++a)
    edges.col(a) =
        x.segment(d * nodes[static_cast<std::size_t>(a) + 1], d) - x.segment(d * nodes[0], d);
  return edges.determinant();
}

}  // namespace

int InvertedElements(const Scene& scene, const Vector& u) {
  if (scene.reference.kind != Reference::Kind::kFem) return 0;
  const int d = scene.dimension;
  const Vector deformed = scene.rest + u;
  int inverted = 0;
  for (const std::vector<int>& element : scene.reference.fem.elements) {
    if (static_cast<int>(element.size()) != d + 1) continue;
    const double before = SignedVolume(element, scene.rest, d);
    const double after = SignedVolume(element, deformed, d);
    inverted += before * after <= 0.0 ? 1 : 0;
  }
  return inverted;
}

ScaledLoad ScaleLoad(const Vector& force, const Vector& prescribed, double amplitude) {
  return {amplitude * force,
          prescribed.size() == 0 ? Vector::Zero(force.size()) : Vector(amplitude * prescribed)};
}

void CheckAmplitudes(const OptionsCheck& check, const std::vector<double>& amplitudes) {
  check.Require(!amplitudes.empty(), "amplitudes", 0.0, "at least one amplitude");
  for (std::size_t i = 0; i < amplitudes.size(); ++i) {
    check.Require(amplitudes[i] > 0.0 && amplitudes[i] <= 20.0, "amplitudes", amplitudes[i],
                  "every value in (0, 20]");
    if (i > 0)
      check.Require(amplitudes[i] > amplitudes[i - 1], "amplitudes", amplitudes[i], "ascending");
  }
}

std::vector<int> EvenlySpread(const std::vector<int>& items, int limit) {
  if (static_cast<int>(items.size()) <= limit) return items;
  std::vector<int> some;
  for (int i = 0; i < limit; ++i)
    some.push_back(
        items[static_cast<std::size_t>(i) * items.size() / static_cast<std::size_t>(limit)]);
  return some;
}

}  // namespace springfit::response
