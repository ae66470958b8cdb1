#include "engine/problem.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <string>

#include "engine/candidates.h"
#include "engine/direct/force_balance.h"
#include "engine/direct/nnls.h"
#include "engine/fem/closed_form_baseline.h"
#include "engine/fem/fem_equilibrium.h"
#include "engine/fem/traction.h"
#include "engine/input_error.h"
#include "engine/number_text.h"
#include "engine/scene_validation.h"

namespace springfit {
namespace {

// A force-balance weight below this fraction of the largest is an absent spring's (round-off or
// noise), left out of the positions reference's training stiffness.
constexpr double kPresentWeight = 1e-3;

// Reference positions of a constrained node may differ from its prescribed position by this
// fraction of the scene's longest candidate (round-off in exported data), no more.
constexpr double kPrescribedMismatchTolerance = 1e-9;

// A reference MSS's equilibrium must be determined to this fraction of its load at least: a
// load whose forces are closer to round-off than this does not tell topologies apart.
constexpr double kReferenceResolution = 1e-3;
// A reference equilibrium that round-off leaves uncertain by more than its own size
// (ReferenceSolve::resolution) is no data: the scene is refused.
constexpr double kReferenceUndetermined = 1.0;

// Newton iterations allowed to the reference MSS's equilibria (see Problem::Problem).
constexpr int kReferenceMaxIterations = 1000;

std::string CasePath(std::size_t k) {
  return "load_cases[" + std::to_string(k) + "]";
}

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

// The FEM reference's equilibria (engine/fem/): one solver per set of free nodes.
void SolveFemReference(const Scene& s, const std::vector<FreeNodes>& free_sets,
                       std::vector<PreparedLoadCase>& load_cases, Interruption* interruption) {
  const fem::FemModel model = fem::FemModel::Build(s);
  std::vector<fem::FemEquilibriumSolver> solvers;
  solvers.reserve(free_sets.size());
  for (const FreeNodes& free : free_sets) {
    solvers.emplace_back(model, free);
    solvers.back().set_interruption(interruption);
  }
  for (std::size_t k = 0; k < load_cases.size(); ++k) {
    PreparedLoadCase& lc = load_cases[k];
    const fem::FemSolveSummary summary =
        solvers[lc.free_set].Solve(lc.force, lc.prescribed, lc.reference);
    if (!summary.converged()) {
      throw InputError("reference",
                       "the FEM reference under " + CasePath(k) + ": " + summary.message);
    }
    lc.reference_solve =
        ReferenceSolve{summary.iterations, summary.load_steps, summary.final_residual};
  }
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
  for (const Material& m : s.reference.fem.materials)
    if (m.model != MaterialModel::kLinear) return notices;
  const double size = BoundingBox::Of(s.dimension, s.rest).Diagonal();
  if (!(size > 0.0)) return notices;
  for (std::size_t k = 0; k < problem.load_cases().size(); ++k) {
    const Vector& u = problem.load_cases()[k].reference;
    double largest = 0.0;
    int node = 0;
    for (int i = 0; i < s.node_count(); ++i) {
      const double d = u.segment(s.dimension * i, s.dimension).norm();
      if (d > largest) {
        largest = d;
        node = i;
      }
    }
    if (largest > kLargeDisplacementFraction * size) {
      char text[400];
      std::snprintf(text, sizeof text,
                    "load_cases[%zu] ('%s'): the linear reference moves node %d by %.0f%% of the "
                    "body's size; a linear material is a small-strain model, so its response at "
                    "this load means little (scale the loads down: the linear fit does not "
                    "depend on their size; or use a nonlinear material)",
                    k, s.load_cases[k].name.c_str(), node, 100.0 * largest / size);
      notices.push_back(text);
    }
  }
  return notices;
}

Problem::Problem(Scene scene, EquilibriumOptions solver_options, Interruption* interruption) {
  ValidateScene(scene);
  ThrowIfInterrupted(interruption);
  Problem& p = *this;
  p.scene_ = std::move(scene);
  const Scene& s = p.scene_;
  p.response_ = ResolveResponse(s);
  solver_options.response = p.response_;
  p.solver_options_ = solver_options;
  const int d = s.dimension;
  const int n = s.node_count();
  p.training_stiffness_ = s.EffectiveTrainingStiffness();
  std::optional<fem::ClosedFormModel> closed_form;
  if (!s.training_stiffness && s.reference.kind == Reference::Kind::kFem) {
    // An FEM reference has no spring stiffness: the training springs take the median of the
    // closed-form recipe's on the mesh edges (engine/fem/closed_form_baseline.h), which has the
    // material's scale (a stiffness of 1 would be off by the Young's modulus).
    closed_form = fem::VanGelderModel(s);
    std::vector<double> k = closed_form->stiffness;
    std::nth_element(k.begin(), k.begin() + static_cast<std::ptrdiff_t>(k.size() / 2), k.end());
    p.training_stiffness_ = k[k.size() / 2];
  }
  p.candidates_ = SpringGeometry(d, s.rest, GenerateCandidates(s));
  if (p.candidates_.size() == 0) throw InputError("candidates", "generates no candidate spring");
  ThrowIfInterrupted(interruption);

  // Load cases and the distinct sets of free nodes they induce.
  std::vector<bool> constrained_anywhere_never_free(n, true);
  for (const LoadCase& lc : s.load_cases) {
    PreparedLoadCase prepared;
    std::vector<bool> constrained;
    Flatten(s, lc, CasePath(p.load_cases_.size()), prepared.force, prepared.prescribed,
            constrained);
    FreeNodes free = FreeNodes::FromConstrained(constrained);
    const auto it = std::find(p.free_sets_.begin(), p.free_sets_.end(), free);
    prepared.free_set = static_cast<int>(it - p.free_sets_.begin());
    if (it == p.free_sets_.end()) p.free_sets_.push_back(std::move(free));
    for (int i = 0; i < n; ++i) {
      if (!constrained[i]) constrained_anywhere_never_free[i] = false;
    }
    p.load_cases_.push_back(std::move(prepared));
  }

  // Genes: candidates with at least one node free in some load case.
  for (int c = 0; c < p.candidates_.size(); ++c) {
    const NodePair& pair = p.candidates_.pairs[c];
    if (constrained_anywhere_never_free[pair.first] &&
        constrained_anywhere_never_free[pair.second]) {
      p.unidentifiable_.push_back(c);
      // (Its stiffness: the closed-form model's on a mesh edge, else the training stiffness.)
      double k = p.training_stiffness_;
      if (closed_form) {
        const NodePair ordered{std::min(pair.first, pair.second),
                               std::max(pair.first, pair.second)};
        const auto it =
            std::lower_bound(closed_form->springs.begin(), closed_form->springs.end(), ordered);
        if (it != closed_form->springs.end() && *it == ordered)
          k = closed_form->stiffness[static_cast<std::size_t>(it - closed_form->springs.begin())];
      }
      p.unidentifiable_stiffness_.push_back(k);
    } else {
      p.gene_candidate_.push_back(c);
    }
  }

  // The reference's equilibria.
  const Reference& ref = s.reference;
  if (ref.kind == Reference::Kind::kMss) {
    const SpringGeometry geometry(d, s.rest, ref.springs);
    ActiveSprings springs;
    for (int m = 0; m < geometry.size(); ++m) {
      springs.index.push_back(m);
      springs.stiffness.push_back(ref.stiffness.size() == 1 ? ref.stiffness[0] : ref.stiffness[m]);
    }
    // The reference is solved once per scene, from rest, where a hard load can take the
    // projected Hessian's linear convergence for a hundred iterations and more (a 1 um line
    // of nodes pulled to 65% stretch needs 138): it gets a larger, still bounded, budget.
    EquilibriumOptions reference_options = solver_options;
    reference_options.max_iterations =
        std::max(solver_options.max_iterations, kReferenceMaxIterations);
    std::vector<EquilibriumSolver> solvers;
    for (const FreeNodes& free : p.free_sets_)
      solvers.emplace_back(geometry, free, reference_options);
    // The reference's equilibria are data: every identification compares against them, and
    // strategy direct reads stiffness off their force balance, where a soft spring's force
    // can be 1e-8 of a stiff one's. So after the ordinary solve, Newton steps continue down
    // to round-off (a few more iterations, once per scene); a polished solution is kept only
    // where it balances the forces better.
    EquilibriumOptions polish_options = solver_options;
    polish_options.relative_force_tolerance = 0.0;
    polish_options.roundoff_force_tolerance = 1e-16;
    polish_options.max_iterations = 4;
    std::vector<EquilibriumSolver> polishers;
    for (const FreeNodes& free : p.free_sets_)
      polishers.emplace_back(geometry, free, polish_options);
    for (auto* list : {&solvers, &polishers}) {
      for (EquilibriumSolver& solver : *list) solver.set_interruption(interruption);
    }
    // The solvers stop between Newton iterations; a stopped solve has no reference to keep.
    const auto stop_if_interrupted = [](const EquilibriumSummary& summary) {
      if (summary.termination == Termination::kInterrupted) throw Interrupted();
    };
    for (std::size_t k = 0; k < p.load_cases_.size(); ++k) {
      ThrowIfInterrupted(interruption);
      PreparedLoadCase& lc = p.load_cases_[k];
      EquilibriumSolver& solver = solvers[lc.free_set];
      const RestStability stability = solver.RestStabilityOf(springs);
      if (stability.modes > 0) {
        throw InputError("reference", "the reference MSS is a mechanism under " + CasePath(k) +
                                          " (" + std::to_string(stability.modes) +
                                          " free modes): it cannot carry the load");
      }
      lc.reference = Vector::Zero(d * n);
      const EquilibriumSummary summary =
          solver.Solve(springs, lc.force, lc.prescribed, lc.reference);
      stop_if_interrupted(summary);
      if (summary.tolerance > kReferenceResolution) {
        throw InputError(CasePath(k),
                         "the load is too small for double precision: round-off in the reference "
                         "springs' forces is " +
                             NumberText(summary.tolerance) +
                             " of it (stiff springs at the loaded nodes hide the soft ones' "
                             "forces), so its equilibrium is not determined; scale the loads "
                             "up (at least " +
                             NumberText(summary.tolerance / kReferenceResolution, 2) + " times)");
      }
      if (!summary.converged()) {
        throw InputError("reference", "no equilibrium of the reference MSS found under " +
                                          CasePath(k) + ": " + NotConvergedText(summary) +
                                          PrecisionLimitText(stability, springs));
      }
      Vector polished = lc.reference;
      const EquilibriumSummary polish =
          polishers[lc.free_set].Solve(springs, lc.force, lc.prescribed, polished);
      stop_if_interrupted(polish);
      lc.reference_solve = ReferenceSolve{summary.iterations, 1, summary.final_residual};
      if (polish.final_residual < summary.final_residual) {
        lc.reference = std::move(polished);
        lc.reference_solve->iterations += polish.iterations;
        lc.reference_solve->residual = polish.final_residual;
      }
      // Measured with the first solver's tolerances (the polisher's are round-off's own).
      const FreeNodes& free = p.free_sets_[lc.free_set];
      double norm2 = 0.0;
      for (int i = 0; i < n; ++i) {
        if (free.free_index[i] >= 0) norm2 += lc.reference.segment(d * i, d).squaredNorm();
      }
      const EquilibriumSolver::Resolution resolution =
          solver.DisplacementResolution(springs, lc.reference);
      lc.reference_solve->stable = resolution.stable;
      lc.reference_solve->resolution = norm2 > 0.0 ? resolution.spread / std::sqrt(norm2)
                                                   : (resolution.spread > 0.0 ? 1.0 : 0.0);
      if (std::isinf(resolution.spread)) {
        throw InputError(CasePath(k),
                         "the reference's equilibrium is not determined: its tangent stiffness "
                         "there is singular" +
                             std::string(resolution.stable ? "" : " (an unstable equilibrium)") +
                             ", so any force imbalance, round-off's included, moves it freely");
      }
      if (lc.reference_solve->resolution > kReferenceUndetermined) {
        throw InputError(CasePath(k),
                         "the reference's equilibrium is not determined in double precision: "
                         "round-off in its springs' forces leaves its displacements uncertain "
                         "by " +
                             NumberText(lc.reference_solve->resolution, 2) +
                             " times their size (a load this small next to stiff springs, or a "
                             "nearly singular stiffness); scale the load up");
      }
    }
    // The reference topology as a candidate mask.
    std::vector<std::uint8_t> mask(p.candidates_.size(), 0);
    for (const NodePair& spring : ref.springs) {
      const NodePair ordered{std::min(spring.first, spring.second),
                             std::max(spring.first, spring.second)};
      const int c = p.CandidateIndex(ordered);
      if (c < 0) {
        p.reference_outside_.push_back(ordered);
      } else {
        mask[c] = 1;
      }
    }
    if (p.reference_outside_.empty()) {
      p.reference_genome_ = p.GenomeFromMask(mask);
      p.reference_mask_ = std::move(mask);
    }
  } else if (ref.kind == Reference::Kind::kFem) {
    SolveFemReference(p.scene_, p.free_sets_, p.load_cases_, interruption);
  } else {
    const double tol = kPrescribedMismatchTolerance * p.candidates_.MaxRestLength();
    for (std::size_t k = 0; k < p.load_cases_.size(); ++k) {
      PreparedLoadCase& lc = p.load_cases_[k];
      lc.reference = ref.positions[k] - s.rest;
      const FreeNodes& free = p.free_sets_[lc.free_set];
      for (int i = 0; i < n; ++i) {
        if (free.free_index[i] >= 0) continue;
        if ((lc.reference.segment(d * i, d) - lc.prescribed.segment(d * i, d)).norm() > tol) {
          throw InputError(
              "reference.positions[" + std::to_string(k) + "][" + std::to_string(i) + "]",
              "node " + std::to_string(i) + " is constrained in " + CasePath(k) +
                  " but its reference position differs from the prescribed one");
        }
        lc.reference.segment(d * i, d) = lc.prescribed.segment(d * i, d);
      }
    }
  }

  for (std::size_t k = 0; k < p.load_cases_.size(); ++k) {
    PreparedLoadCase& lc = p.load_cases_[k];
    const FreeNodes& free = p.free_sets_[lc.free_set];
    lc.reference_norm2 = 0.0;
    for (int i = 0; i < n; ++i) {
      if (free.free_index[i] >= 0)
        lc.reference_norm2 += lc.reference.segment(d * i, d).squaredNorm();
    }
    p.reference_norm2_ += lc.reference_norm2;
  }
  if (!(p.reference_norm2_ > 0.0)) {
    throw InputError("reference", "the reference does not move any free node: nothing to match");
  }
  if (!s.training_stiffness && ref.kind == Reference::Kind::kPositions)
    p.training_stiffness_ = PositionsTrainingStiffness(p);
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
