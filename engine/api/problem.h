// The engine's public surface (engine/api/): a scene prepared for identification, and the
// cost of one topology against its reference.
//
// A scene prepared for identification (Problem, engine/problem/problem.cpp): everything
// derived from it that every evaluation of a topology needs, computed once.
//
// - the candidate springs and their rest geometry; the genome: one gene per candidate that
//   some load case can see (a candidate whose two nodes are constrained in every load case
//   exerts no force on a free node: it is left out and reported as unidentifiable);
// - per load case: which nodes are free (load cases that constrain the same nodes share one
//   EquilibriumSolver pattern), the external forces and the prescribed displacements;
// - the reference's equilibrium displacements u^R per load case (solved here for an MSS
//   reference, taken from the scene otherwise) and their squared norms, which normalise the
//   cost; the reference topology as a candidate mask when every reference spring is a
//   candidate.
// Immutable after Build(); safe to share between threads.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "engine/api/model.h"
#include "engine/api/scene.h"
#include "engine/runtime/interruption.h"

namespace springfit {

struct IdentifiabilityReport;  // engine/api/analysis.h
namespace fem {
struct ClosedFormModel;  // engine/fem/closed_form_baseline.h
}
class Problem;

// How the reference's equilibrium of a load case was solved (MSS and FEM references; absent
// for positions).
struct ReferenceSolve {
  int iterations = 0;     // Newton iterations
  int load_steps = 1;     // load increments (FEM continuation; 1 = the full load at once)
  double residual = 0.0;  // final |gradient|_inf relative to the case's force scale
  // MSS references: how far round-off leaves the equilibrium undetermined, relative to it:
  // EquilibriumSolver::DisplacementResolution over |u^R| on the free nodes (0 for FEM). A
  // normalised error below it cannot be told from 0; a stiffness spread near 1e12 or nearly
  // collinear springs can make it large (problem.cpp warns beyond kReferenceResolutionWarning).
  double resolution = 0.0;
  // MSS references: false when the equilibrium is unstable, a saddle of the energy rather than
  // a minimum (its exact tangent is not positive definite: a straight chain compressed past
  // buckling stays straight by symmetry). The reference MSS would leave it at the slightest
  // disturbance; `check` and `reference` say so.
  bool stable = true;
};

// A reference whose displacements round-off leaves undetermined beyond this (relative) is
// named in `springfit check` and `reference`: errors below it are noise.
inline constexpr double kReferenceResolutionWarning = 1e-6;

struct PreparedLoadCase {
  int free_set = 0;              // index into Problem::free_sets
  Vector force;                  // flat d*n
  Vector prescribed;             // flat d*n, zero on free nodes
  Vector reference;              // u^R, flat d*n
  double reference_norm2 = 0.0;  // sum over free nodes of |u^R_i|^2
  std::optional<ReferenceSolve> reference_solve;
};

// How a genome differs from the reference topology, over the genes (unidentifiable
// candidates are not compared: no load case can tell them).
struct TopologyDifference {
  std::vector<NodePair> missing;  // reference springs the genome lacks
  std::vector<NodePair> extra;    // genome springs the reference lacks
  int hamming() const { return static_cast<int>(missing.size() + extra.size()); }
};

// search.response, or its default: linear for an FEM reference whose materials are all linear
// (it describes the small-load limit: comparing it with springs that turn, stiffen and buckle
// at the FEM's load would mix a load-level artefact into the model error), nonlinear otherwise.
Response ResolveResponse(const Scene& scene);

// Notices about the scene that are not errors, one line each: a Poisson's ratio near 0.5, where
// linear elements lock. `run` and `check` print them. (A linear reference loaded past small
// strain is a warning of its own: SmallStrainWarning below.)
// A Poisson's ratio above this gets a notice: linear elements lock near 0.5.
inline constexpr double kLockingPoisson = 0.49;
std::vector<std::string> SceneNotices(const Problem& problem);

// A scene prepared for identification: validated (the one place a scene's rules are checked),
// its reference's equilibria solved, its candidates and genes laid out. Prepared once per job
// and shared by everything that reads it, from any number of threads. It cannot be copied or
// moved: solvers and cost functions keep pointers into it (its candidate geometry), which a
// move would leave dangling. Keep it where it was built, or behind a pointer.
class Problem {
 public:
  // Validates `scene` (ValidateScene) and prepares it. Throws InputError when the scene is
  // invalid or its reference MSS has no equilibrium (a mechanism, or no convergence) under
  // some load case. Preparing a large scene takes seconds to minutes (its reference's Newton
  // iterations, each a sparse factorisation): `interruption`, when set, is checked between
  // them and stops the preparation by throwing Interrupted.
  explicit Problem(Scene scene, EquilibriumOptions solver_options = {},
                   Interruption* interruption = nullptr);
  // The same for a scene already validated (ValidScene, engine/api/scene.h): it is not checked
  // again.
  explicit Problem(ValidScene scene, EquilibriumOptions solver_options = {},
                   Interruption* interruption = nullptr);
  // The same, for `const Problem p = Problem::Build(scene);` (no copy or move is made).
  static Problem Build(Scene scene, EquilibriumOptions solver_options = {},
                       Interruption* interruption = nullptr) {
    return Problem(std::move(scene), solver_options, interruption);
  }
  Problem(const Problem&) = delete;
  Problem& operator=(const Problem&) = delete;
  Problem(Problem&&) = delete;
  Problem& operator=(Problem&&) = delete;

  const Scene& scene() const { return scene_; }
  int dimension() const { return scene_.dimension; }
  const SpringGeometry& candidates() const { return candidates_; }
  const std::vector<FreeNodes>& free_sets() const { return free_sets_; }
  const std::vector<PreparedLoadCase>& load_cases() const { return load_cases_; }
  // Its `response` is the problem's.
  const EquilibriumOptions& solver_options() const { return solver_options_; }
  // How the training model (and an MSS reference) responds to the loads: the scene's
  // search.response, else ResolveResponse's rule.
  Response response() const { return response_; }

  int gene_count() const { return static_cast<int>(gene_candidate_.size()); }
  // The candidate index of each gene, ascending.
  const std::vector<int>& gene_candidates() const { return gene_candidate_; }
  // Candidates no load case can see (both nodes held in every load case).
  const std::vector<int>& unidentifiable() const { return unidentifiable_; }
  // Their stiffness in every model, parallel to unidentifiable(): no fit can tell it, but under
  // other supports (a simulator's, the probe bank's) they hold the body. The closed-form
  // model's on an FEM reference's mesh edge (not fitted: the baseline is the best guess there),
  // the training stiffness otherwise. Exports write them (io/spring_model.h); the rest-linear
  // stiffness of a model includes them (engine/problem/rest_stiffness.h).
  const std::vector<double>& unidentifiable_stiffness() const { return unidentifiable_stiffness_; }
  // The scene's `stiffness`, else: an MSS reference's single stiffness, the closed-form
  // baseline's median on an FEM reference, PositionsTrainingStiffness on a positions one.
  double training_stiffness() const { return training_stiffness_; }
  // sum over load cases of reference_norm2: the normaliser of the cost.
  double reference_norm2() const { return reference_norm2_; }

  // The reference topology over the candidates, when every reference spring is a candidate
  // (an MSS reference only).
  const std::optional<std::vector<std::uint8_t>>& reference_mask() const { return reference_mask_; }
  // The reference's springs that are not candidates (empty when reference_mask() exists).
  const std::vector<NodePair>& reference_non_candidates() const { return reference_outside_; }

  // The reference topology as a genome (when reference_mask() exists).
  const std::optional<Genome>& reference_genome() const { return reference_genome_; }
  // nullopt when the reference topology is unknown.
  std::optional<TopologyDifference> CompareWithReference(const Genome& genome) const;
  // The springs a genome switches on, ascending.
  std::vector<NodePair> SpringsOfGenome(const Genome& genome) const;

  // Genome <-> candidate mask (unidentifiable candidates are 0 in a mask from a genome).
  std::vector<std::uint8_t> MaskFromGenome(const Genome& genome) const;
  Genome GenomeFromMask(const std::vector<std::uint8_t>& mask) const;
  // The springs of a candidate mask, with the training stiffness.
  ActiveSprings SpringsFromMask(const std::vector<std::uint8_t>& mask) const;
  // The springs of the genes with a positive weight, each with its weight as stiffness.
  ActiveSprings SpringsOfWeights(const std::vector<double>& weights) const;
  // Index of candidate (i, j), i < j (as candidates and a read result hold them), or -1.
  int CandidateIndex(NodePair pair) const;
  // Per gene, the reference's stiffness of that spring, 0 where the reference has none (what
  // strategy direct should find). Empty for a positions reference.
  std::vector<double> ReferenceWeights() const;
  // No load case puts a force on a free node: prescribed displacements alone load the model,
  // so the data fix the stiffness only up to one common factor (engine/direct/scale_pinning.h).
  bool DisplacementOnly() const;

 private:
  friend const IdentifiabilityReport& Identifiability(const Problem& problem,
                                                      Interruption* interruption);

  // The steps of preparing, in the constructor's order (the reference's equilibria:
  // reference_equilibria.h).
  // Flattens each load case's loads and finds the distinct sets of free nodes.
  void PrepareLoadCases();
  // A gene per candidate that some load case can see; the rest are unidentifiable.
  void ChooseGenes();
  // The reference's displacements under every load case, by the reference's kind.
  void SolveReference(Interruption* interruption);
  // An MSS reference's topology as a candidate mask, or its springs outside the candidates.
  void TakeReferenceTopology();
  // The reference's squared norms over the free nodes, which normalise the cost.
  void NormaliseByReference();
  // The unidentifiable springs' stiffness: the closed-form model's on a mesh edge (when
  // given), else the training stiffness, once it is final (a positions reference's comes from
  // its force balance, which needs the genes and the reference: it was 1 before it).
  void StiffenUnseenSprings(const fem::ClosedFormModel* closed_form);

  Scene scene_;
  EquilibriumOptions solver_options_;
  Response response_ = Response::kNonlinear;
  SpringGeometry candidates_;
  std::vector<FreeNodes> free_sets_;
  std::vector<PreparedLoadCase> load_cases_;
  std::vector<int> gene_candidate_;
  std::vector<int> unidentifiable_;
  std::vector<double> unidentifiable_stiffness_;
  double training_stiffness_ = 1.0;
  double reference_norm2_ = 0.0;
  std::optional<std::vector<std::uint8_t>> reference_mask_;
  std::optional<Genome> reference_genome_;
  std::vector<NodePair> reference_outside_;
  // Identifiability(): computed on first use, once.
  mutable std::once_flag identifiability_once_;
  mutable std::shared_ptr<const IdentifiabilityReport> identifiability_;
};

// One line when a linear FEM reference is strained past small strain (kSmallStrainLimit,
// engine/problem/small_strain.h) at `load_size` (the scene's length; 0 for the named loads' own
// size): where, how much, and what to use instead.
std::optional<std::string> SmallStrainWarning(const Problem& problem, double load_size = 0.0);

// The cost of a topology: how far its equilibria are from the reference's
// (engine/problem/cost.h says how, and what a model that cannot carry the loads scores).
struct LoadCaseEvaluation {
  double cost = 0.0;              // sum_i |X^R_i - X^M_i|^2 for this case (penalised if unstable)
  double normalized_error = 0.0;  // cost / sum_i |u^R_i|^2 of this case
  EquilibriumSummary solve;
};

struct Evaluation {
  double cost = 0.0;
  double normalized_error = 0.0;
  bool mechanism = false;   // some load case found a singular rest stiffness
  bool converged = true;    // every solve converged (false for mechanisms too)
  int mechanism_modes = 0;  // summed over load cases
  // Stopped by the CostFunction's Interruption before it was complete: cost and error mean
  // nothing (the caller abandons the evaluation).
  bool interrupted = false;
  std::vector<LoadCaseEvaluation> load_cases;
};

struct CostOptions {
  enum class WarmStart {
    kReference,  // start each solve from the reference's equilibrium (close for near-right
                 // topologies, the common case late in a search)
    kRest,       // start from the rest configuration
  };
  WarmStart warm_start = WarmStart::kReference;
  // A mechanism's penalty depends on its modes alone, known from the rest factorisations:
  // false skips the other load cases' solves (termination kNotSolved), which a search never
  // reads; true solves them for a per-case report (`springfit eval`).
  bool solve_cases_of_mechanisms = false;
  // The springs' law for these evaluations; none: the problem's (Problem::response). An export
  // predicts what a simulator computes, so it asks for kNonlinear whatever the problem's.
  std::optional<Response> response;
};

// Evaluates topologies of one Problem (engine/problem/cost.cpp). Holds one equilibrium solver
// per distinct set of free nodes (their symbolic analysis was done once), behind a handle: the
// surface does not see the solvers. Not thread-safe: one per thread; the Problem must outlive
// it.
class CostFunction {
 public:
  explicit CostFunction(const Problem& problem, CostOptions options = {});
  ~CostFunction();
  CostFunction(CostFunction&&) noexcept;
  CostFunction& operator=(CostFunction&&) noexcept;

  const Problem& problem() const { return *problem_; }
  // Checked between the Newton iterations of every solve (nullptr: never stopped).
  void set_interruption(Interruption* interruption);

  Evaluation EvaluateGenome(const Genome& genome);
  Evaluation EvaluateMask(const std::vector<std::uint8_t>& candidate_mask);
  // Any springs over the candidate geometry (per-spring stiffness allowed). When
  // `displacements` is given it receives the equilibrium displacements u per load case
  // (empty for a load case without equilibrium).
  Evaluation Evaluate(const ActiveSprings& springs, std::vector<Vector>* displacements = nullptr);

 private:
  struct Solvers;  // the equilibrium solvers and their rest verdicts (cost.cpp)

  // Stability first: fills the rest verdicts (one rest factorisation per free set); true when
  // some set has a mechanism.
  bool CheckStability(const ActiveSprings& springs);

  const Problem* problem_;
  CostOptions options_;
  std::unique_ptr<Solvers> solvers_;
  Vector u_;
};

}  // namespace springfit
