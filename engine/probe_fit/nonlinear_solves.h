// Nonlinear equilibria of a probe's loads, shared by the nonlinear judgement
// (amplitude_judgement.h) and the nonlinear fit (nonlinear_response.h): a spring model solved
// with the simulator's spring law (springs.h), the reference with its own law (the FEM model's
// St. Venant-Kirchhoff or neo-Hookean solve, or the reference MSS's), and the relative error
// between them.
#pragma once

#include <optional>
#include <vector>

#include "engine/api/problem.h"
#include "engine/fem/fem_equilibrium.h"
#include "engine/model/equilibrium.h"
#include "engine/runtime/options_check.h"

namespace springfit::response {

// Springs over the scene's nodes with their stiffness.
struct SpringModel {
  std::vector<NodePair> pairs;
  std::vector<double> stiffness;  // > 0, parallel to pairs
};
// The model of per-gene `weights` (0: absent) with the candidates no load case sees at
// Problem::unidentifiable_stiffness, as SpringRestStiffness(problem, weights) has them.
SpringModel ModelOfWeights(const Problem& problem, const std::vector<double>& weights);
// The reference's own springs (an MSS reference).
SpringModel ReferenceSprings(const Scene& scene);

// A spring model as an equilibrium solver's geometry and springs.
struct SpringSolverInput {
  SpringGeometry geometry;
  ActiveSprings springs;
  SpringSolverInput(const Scene& scene, const SpringModel& model);
};

// A spring model's equilibria on one support, each solve warm-started from the last.
class SpringResponse {
 public:
  SpringResponse(const SpringSolverInput& input, const FreeNodes& free,
                 const EquilibriumOptions& options, Interruption* interruption);
  // The displacement (flat d*n) under (force, prescribed), or nothing (a mechanism, no
  // convergence). A load step: the solve starts from the last equilibrium scaled by the ratio
  // of this load's size to the last one's (its linear prediction) and, with the options'
  // chord_contraction, from the last solve's tangent. Throws Interrupted when stopped.
  std::optional<Vector> Solve(const Vector& force, const Vector& prescribed);
  // How the last Solve went (its Newton and chord steps), for tests and reports.
  const EquilibriumSummary& last_summary() const { return last_summary_; }

 private:
  const SpringSolverInput& input_;
  EquilibriumSolver solver_;
  EquilibriumSummary last_summary_;
  bool held_ = false;
  Vector last_;             // the last equilibrium (empty: none)
  double last_size_ = 0.0;  // |(force, prescribed)| of its load
};

// Chord steps of load steps (EquilibriumOptions::chord_contraction): a step refactorises when
// the one before shrank the force imbalance by less than tenfold (docs/ARCHITECTURE.md, "The
// nonlinear fit"; bench/RESULTS.md, round nine, has the thresholds tried).
inline constexpr double kLoadStepChordContraction = 0.1;
// The problem's solver options for load steps (SpringResponse's solves of a probe at
// increasing sizes): with kLoadStepChordContraction, and the simulator's spring law (nonlinear
// springs) whatever the problem's response, as every load-stepped solve judges or fits the
// model as the simulator runs it.
EquilibriumOptions LoadStepSolverOptions(const Problem& problem);

// A probe's loads at `amplitude` of their size: the force and the prescribed displacements (an
// empty `prescribed` is none).
struct ScaledLoad {
  Vector force;
  Vector prescribed;
};
ScaledLoad ScaleLoad(const Vector& force, const Vector& prescribed, double amplitude);

// The reference's response to a probe's loads on one support: the FEM model's nonlinear solve,
// or the reference MSS's. Checked for a stop at every Newton iteration too: a probe of a large
// nonlinear mesh is nine solves.
class ReferenceSolver {
 public:
  ReferenceSolver(const std::optional<fem::FemModel>& fem,
                  const std::optional<SpringSolverInput>& springs, const FreeNodes& free,
                  const Problem& problem, Interruption* interruption);
  // nullopt where the reference has no equilibrium.
  std::optional<Vector> Solve(const Vector& force, const Vector& prescribed);
  // The response at `amplitude` of a probe's own size, whose response there `at_size` is known
  // (the bank's, from the rest stiffness): for a reference linear at every size (an FEM model
  // whose materials are all linear) that response scaled, without a solve (in 3D a probe's
  // solves cost as much as the springs' there); else Solve of the scaled load.
  std::optional<Vector> SolveAt(const ScaledLoad& load, const Vector& at_size, double amplitude);

 private:
  const fem::FemModel* fem_model_ = nullptr;
  FreeNodes free_;
  Interruption* interruption_ = nullptr;
  std::optional<fem::FemEquilibriumSolver> fem_;  // made at the first solve that needs it
  std::optional<SpringResponse> springs_;
  bool linear_ = false;
};

// The reference model of a problem for ReferenceSolver: its FEM model or its springs (one of
// the two set). Precondition: an FEM or MSS reference.
struct ReferenceModel {
  std::optional<fem::FemModel> fem;
  std::optional<SpringSolverInput> springs;
  explicit ReferenceModel(const Problem& problem);
};

// |model - reference| / |reference| over the free nodes (NaN when the reference is 0).
double RelativeError(const Vector& model, const Vector& reference, const FreeNodes& free, int d);

// The FEM reference's elements that a displacement `u` (flat d*n) turns inside out: the sign of
// their volume (area in 2D) at X + u is not that at rest, or the volume vanishes. A spring model
// whose equilibrium does that has folded the tissue the mesh describes: a simulator's
// collision and rendering meshes invert with it. 0 for a reference without elements.
int InvertedElements(const Scene& scene, const Vector& u);

// Fractions of the named loads' size (an options field `amplitudes`): at least one, each in
// (0, 20], ascending; `check` names the owner.
void CheckAmplitudes(const OptionsCheck& check, const std::vector<double>& amplitudes);

// At most `limit` of `items`, evenly spread over their order (a bank runs support by support,
// family by family, so every part of it is represented).
std::vector<int> EvenlySpread(const std::vector<int>& items, int limit);

}  // namespace springfit::response
