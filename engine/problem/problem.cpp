#include "engine/api/problem.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>

#include <fmt/format.h>

#include "engine/api/scene.h"
#include "engine/fem/closed_form_baseline.h"
#include "engine/fem/traction.h"
#include "engine/genome/gene_weights.h"
#include "engine/linalg/nnls.h"
#include "engine/model/candidates.h"
#include "engine/problem/force_balance.h"
#include "engine/problem/reference_equilibria.h"
#include "engine/runtime/input_error.h"

namespace springfit {

// The training stiffness of a positions reference given without one: the median of the
// springs the force balance at the reference's positions keeps (its non-negative
// least-squares weights above 1e-3 of the largest, engine/linalg/nnls.h): the stiffness the
// data give the springs they need, in the data's units. 1 when the loads only prescribe
// displacements (the data fix no scale).
double PositionsTrainingStiffness(const Problem& problem);
namespace {

// A force-balance weight below this fraction of the largest is an absent spring's (round-off or
// noise), left out of the positions reference's training stiffness.
constexpr double kPresentWeight = 1e-3;

// Reference positions of a constrained node may differ from its prescribed position by this
// fraction of the scene's longest candidate (round-off in exported data), no more.
constexpr double kPrescribedMismatchTolerance = 1e-9;

// Scatter a case's loads into flat vectors and mark the constrained nodes.
void Flatten(const Scene& scene, const LoadCase& lc, const std::string& path, Vector& force,
             Vector& prescribed, std::vector<bool>& constrained) {
  const int d = scene.dimension;
  const int n = scene.node_count();
  force = Vector::Zero(d * n);
  prescribed = Vector::Zero(d * n);
  constrained.assign(n, false);
  for (int node : lc.fixed) constrained[node] = true;
  for (const NodalLoad& load : lc.displacements) {
    for (int node : load.nodes) {
      constrained[node] = true;
      prescribed.segment(d * node, d) = load.value;
    }
  }
  for (const NodalLoad& load : lc.forces) {
    for (int node : load.nodes) force.segment(d * node, d) += load.value;
  }
  for (std::size_t m = 0; m < lc.tractions.size(); ++m) {
    fem::AddTractionForces(scene, lc.tractions[m], path + ".tractions[" + std::to_string(m) + "]",
                           force);
  }
  // A traction's share on a constrained node is taken by the support (a reaction).
  for (int i = 0; i < n; ++i) {
    if (constrained[i]) force.segment(d * i, d).setZero();
  }
}

// The closed-form model's stiffness of `pair` when it is a mesh edge, else `otherwise`.
double EdgeStiffness(const fem::ClosedFormModel& model, NodePair pair, double otherwise) {
  const NodePair ordered{std::min(pair.first, pair.second), std::max(pair.first, pair.second)};
  const auto it = std::lower_bound(model.springs.begin(), model.springs.end(), ordered);
  if (it == model.springs.end() || !(*it == ordered)) return otherwise;
  return model.stiffness[static_cast<std::size_t>(it - model.springs.begin())];
}

}  // namespace

Response ResolveResponse(const Scene& scene) {
  if (scene.search.response) return *scene.search.response;
  if (scene.reference.kind != Reference::Kind::kFem) return Response::kNonlinear;
  for (const Material& m : scene.reference.fem.materials) {
    if (m.model != MaterialModel::kLinear) return Response::kNonlinear;
  }
  return Response::kLinear;
}

std::vector<std::string> SceneNotices(const Problem& problem) {
  std::vector<std::string> notices;
  const Scene& s = problem.scene();
  if (s.reference.kind != Reference::Kind::kFem) return notices;
  // Linear triangles and tetrahedra lock as nu nears 0.5: the reference turns stiffer than the
  // material it models, and the springs are fitted to that.
  for (std::size_t i = 0; i < s.reference.fem.materials.size(); ++i) {
    const double nu = s.reference.fem.materials[i].poisson;
    if (nu > kLockingPoisson) {
      // Named by the field the user wrote; the bulk modulus over the shear modulus says how
      // near incompressible (2 (1 + nu) / (3 (1 - 2 nu)): 33 at 0.49, 500 at 0.499).
      const std::string field = s.reference.fem.regions
                                    ? fmt::format("reference.materials[{}].poisson", i)
                                    : std::string("reference.material.poisson");
      notices.push_back(fmt::format(
          "{}: Poisson's ratio {} is above {}: linear {} lock there (the volume is {:.3g} times "
          "stiffer than the shear; the reference turns stiffer than the material, most in "
          "bending, and the springs are fitted to that); 0.49 is the usual value for soft "
          "tissue",
          field, nu, kLockingPoisson, s.dimension == 2 ? "triangles" : "tetrahedra",
          2.0 * (1.0 + nu) / (3.0 * (1.0 - 2.0 * nu))));
    }
  }
  return notices;
}

// Preparing a scene, step by step: each step reads what the ones before it set.
Problem::Problem(Scene scene, EquilibriumOptions solver_options, Interruption* interruption)
    : Problem(ValidScene(std::move(scene)), solver_options, interruption) {}

Problem::Problem(ValidScene scene, EquilibriumOptions solver_options, Interruption* interruption) {
  ThrowIfInterrupted(interruption);
  scene_ = std::move(scene).Release();
  response_ = ResolveResponse(scene_);
  solver_options.response = response_;
  solver_options_ = solver_options;
  // An FEM reference's closed-form model gives the training stiffness's scale and the
  // unidentifiable springs' stiffness when the scene has none.
  std::optional<fem::ClosedFormModel> closed_form;
  if (!scene_.training_stiffness && scene_.reference.kind == Reference::Kind::kFem)
    closed_form = fem::VanGelderModel(scene_);
  // An FEM reference has no spring stiffness: the training springs take the median of the
  // closed-form model's, which has the material's scale (1 would be off by Young's modulus).
  training_stiffness_ =
      closed_form ? MedianPositive(closed_form->stiffness) : scene_.EffectiveTrainingStiffness();
  candidates_ = SpringGeometry(scene_.dimension, scene_.rest, GenerateCandidates(scene_));
  if (candidates_.size() == 0) throw InputError("candidates", "generates no candidate spring");
  ThrowIfInterrupted(interruption);
  PrepareLoadCases();
  ChooseGenes();
  SolveReference(interruption);
  NormaliseByReference();
  if (!scene_.training_stiffness && scene_.reference.kind == Reference::Kind::kPositions)
    training_stiffness_ = PositionsTrainingStiffness(*this);
  StiffenUnseenSprings(closed_form ? &*closed_form : nullptr);
}

void Problem::PrepareLoadCases() {
  for (const LoadCase& lc : scene_.load_cases) {
    PreparedLoadCase prepared;
    std::vector<bool> constrained;
    Flatten(scene_, lc, LoadCasePath(load_cases_.size()), prepared.force, prepared.prescribed,
            constrained);
    FreeNodes free = FreeNodes::FromConstrained(constrained);
    const auto it = std::find(free_sets_.begin(), free_sets_.end(), free);
    prepared.free_set = static_cast<int>(it - free_sets_.begin());
    if (it == free_sets_.end()) free_sets_.push_back(std::move(free));
    load_cases_.push_back(std::move(prepared));
  }
}

void Problem::ChooseGenes() {
  // A node constrained in every load case exerts no force on a free node.
  std::vector<bool> never_free(static_cast<std::size_t>(scene_.node_count()), true);
  for (const FreeNodes& free : free_sets_) {
    for (std::size_t i = 0; i < never_free.size(); ++i) {
      if (free.free_index[i] >= 0) never_free[i] = false;
    }
  }
  for (int c = 0; c < candidates_.size(); ++c) {
    const NodePair& pair = candidates_.pairs[c];
    if (!(never_free[pair.first] && never_free[pair.second])) {
      gene_candidate_.push_back(c);
      continue;
    }
    unidentifiable_.push_back(c);
  }
}

void Problem::StiffenUnseenSprings(const fem::ClosedFormModel* closed_form) {
  for (const int c : unidentifiable_) {
    const NodePair& pair = candidates_.pairs[static_cast<std::size_t>(c)];
    unidentifiable_stiffness_.push_back(
        closed_form ? EdgeStiffness(*closed_form, pair, training_stiffness_) : training_stiffness_);
  }
}

void Problem::SolveReference(Interruption* interruption) {
  switch (scene_.reference.kind) {
    case Reference::Kind::kMss:
      SolveMssReference(scene_, free_sets_, solver_options_, load_cases_, interruption);
      TakeReferenceTopology();
      break;
    case Reference::Kind::kFem:
      SolveFemReference(scene_, free_sets_, load_cases_, interruption);
      break;
    case Reference::Kind::kPositions:
      TakePositionsReference(scene_, free_sets_,
                             kPrescribedMismatchTolerance * candidates_.MaxRestLength(),
                             load_cases_);
      break;
  }
}

void Problem::TakeReferenceTopology() {
  std::vector<std::uint8_t> mask(candidates_.size(), 0);
  for (const NodePair& spring : scene_.reference.springs) {
    const NodePair ordered{std::min(spring.first, spring.second),
                           std::max(spring.first, spring.second)};
    const int c = CandidateIndex(ordered);
    if (c < 0) {
      reference_outside_.push_back(ordered);
    } else {
      mask[c] = 1;
    }
  }
  if (reference_outside_.empty()) {
    reference_genome_ = GenomeFromMask(mask);
    reference_mask_ = std::move(mask);
  }
}

void Problem::NormaliseByReference() {
  const int d = scene_.dimension;
  for (PreparedLoadCase& lc : load_cases_) {
    const FreeNodes& free = free_sets_[lc.free_set];
    lc.reference_norm2 = 0.0;
    for (int i = 0; i < scene_.node_count(); ++i) {
      if (free.free_index[i] >= 0)
        lc.reference_norm2 += lc.reference.segment(d * i, d).squaredNorm();
    }
    reference_norm2_ += lc.reference_norm2;
  }
  if (!(reference_norm2_ > 0.0)) {
    throw InputError("reference", "the reference does not move any free node: nothing to match");
  }
}

double PositionsTrainingStiffness(const Problem& problem) {
  // Loads that only prescribe displacements fix no scale (scale_pinning.h).
  if (problem.DisplacementOnly()) return 1.0;
  const ForceBalance fb = AssembleForceBalance(problem);
  const NnlsResult nnls = SolveNnls(fb.a, fb.b, SeenGenes(fb, kUnseenStrain));
  std::vector<double> present;
  const double largest = nnls.x.size() > 0 ? nnls.x.maxCoeff() : 0.0;
  for (Eigen::Index g = 0; g < nnls.x.size(); ++g) {
    if (nnls.x[g] > kPresentWeight * largest) present.push_back(nnls.x[g]);
  }
  if (present.empty() || !std::isfinite(largest)) return 1.0;
  const auto mid = present.begin() + static_cast<std::ptrdiff_t>(present.size() / 2);
  std::nth_element(present.begin(), mid, present.end());
  return *mid;
}

int Problem::CandidateIndex(NodePair pair) const {
  const auto it = std::lower_bound(candidates_.pairs.begin(), candidates_.pairs.end(), pair);
  if (it == candidates_.pairs.end() || !(*it == pair)) return -1;
  return static_cast<int>(it - candidates_.pairs.begin());
}

bool Problem::DisplacementOnly() const {
  const int d = dimension();
  for (const PreparedLoadCase& lc : load_cases_) {
    const FreeNodes& free = free_sets_[lc.free_set];
    for (int i = 0; i < static_cast<int>(free.free_index.size()); ++i) {
      if (free.free_index[i] >= 0 && lc.force.segment(d * i, d).squaredNorm() > 0.0) return false;
    }
  }
  return true;
}

std::vector<double> Problem::ReferenceWeights() const {
  const Reference& ref = scene_.reference;
  if (ref.kind != Reference::Kind::kMss) return {};
  std::vector<double> w(gene_candidate_.size(), 0.0);
  for (std::size_t s = 0; s < ref.springs.size(); ++s) {
    const NodePair ordered{std::min(ref.springs[s].first, ref.springs[s].second),
                           std::max(ref.springs[s].first, ref.springs[s].second)};
    const auto it =
        std::lower_bound(gene_candidate_.begin(), gene_candidate_.end(), CandidateIndex(ordered));
    if (it != gene_candidate_.end() && *it == CandidateIndex(ordered)) {
      w[static_cast<std::size_t>(it - gene_candidate_.begin())] =
          ref.stiffness.size() == 1 ? ref.stiffness[0] : ref.stiffness[s];
    }
  }
  return w;
}

std::vector<std::uint8_t> Problem::MaskFromGenome(const Genome& genome) const {
  std::vector<std::uint8_t> mask(candidates_.size(), 0);
  for (std::size_t g = 0; g < gene_candidate_.size(); ++g) mask[gene_candidate_[g]] = genome[g];
  return mask;
}

std::optional<TopologyDifference> Problem::CompareWithReference(const Genome& genome) const {
  if (!reference_genome_) return std::nullopt;
  TopologyDifference diff;
  for (std::size_t g = 0; g < gene_candidate_.size(); ++g) {
    if (genome[g] == (*reference_genome_)[g]) continue;
    (genome[g] ? diff.extra : diff.missing).push_back(candidates_.pairs[gene_candidate_[g]]);
  }
  return diff;
}

std::vector<NodePair> Problem::SpringsOfGenome(const Genome& genome) const {
  std::vector<NodePair> springs;
  for (std::size_t g = 0; g < gene_candidate_.size(); ++g) {
    if (genome[g]) springs.push_back(candidates_.pairs[gene_candidate_[g]]);
  }
  return springs;
}

Genome Problem::GenomeFromMask(const std::vector<std::uint8_t>& mask) const {
  Genome genome(gene_candidate_.size());
  for (std::size_t g = 0; g < gene_candidate_.size(); ++g) genome[g] = mask[gene_candidate_[g]];
  return genome;
}

ActiveSprings Problem::SpringsOfWeights(const std::vector<double>& weights) const {
  ActiveSprings springs;
  for (std::size_t g = 0; g < gene_candidate_.size(); ++g) {
    if (weights[g] > 0.0) {
      springs.index.push_back(gene_candidate_[g]);
      springs.stiffness.push_back(weights[g]);
    }
  }
  return springs;
}

ActiveSprings Problem::SpringsFromMask(const std::vector<std::uint8_t>& mask) const {
  ActiveSprings springs;
  for (int c = 0; c < candidates_.size(); ++c) {
    if (mask[c]) {
      springs.index.push_back(c);
      springs.stiffness.push_back(training_stiffness_);
    }
  }
  return springs;
}

}  // namespace springfit
