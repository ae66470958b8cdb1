// The nonlinear fit's objective (docs/ARCHITECTURE.md, "The nonlinear fit"): the model's
// equilibria under the simulator's spring law at the sizes of the load range, against the
// reference's own nonlinear equilibria there.
//
// The rest-linear fit matches the small-load limit. A simulator loads the model at the size of
// what a tool does, where a nonlinear reference (St. Venant-Kirchhoff, neo-Hookean, an MSS)
// and the springs (which turn and stretch) both leave that limit. So fitted probes are applied
// again at fractions of the named loads' size (`amplitudes`), the reference solved once with its
// own law, and the model's equilibria differentiated exactly in the stiffness through the
// tangent at each equilibrium (the adjoint; spring_sensitivities.h). Choosing probes at the same
// amplitudes, solved the same way, decide every choice; held-out probes are never seen here
// (they are judged at amplitudes by the certificate, amplitude_judgement.h).
#pragma once

#include <atomic>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "engine/api/probe_fit_report.h"
#include "engine/probe_fit/nonlinear_solves.h"
#include "engine/probe_fit/probe_bank.h"
#include "engine/probe_fit/spring_sensitivities.h"

namespace springfit::response {

struct NonlinearFitOptions {
  // Fractions of the named loads' size the model is fitted and chosen at, each in (0, 20],
  // ascending. The smallest anchors the small-load limit the rest-linear fit matched.
  std::vector<double> amplitudes = {0.25, 0.5, 1.0};
  // Generated fitted probes at most, evenly spread over the bank's (the named cases are always
  // in), >= 0; and choosing probes at most, >= 1. Each is a Newton solve, a factorisation and
  // its solves per amplitude at every Gauss-Newton trial.
  int max_fitted_probes = 1000;
  int max_choosing_probes = 1000;
  // The Tikhonov strengths of the continuation toward the rest-linear fit's model, strongest
  // first (each >= 0; regularisation as in ResponseFitOptions::regularizations), and the
  // Gauss-Newton steps per strength (>= 1).
  std::vector<double> regularizations = {1e-2, 1e-3, 1e-4, 1e-5};
  int steps_per_strength = 3;
  // The stage's equilibrium solves take chord steps (EquilibriumOptions::chord_contraction)
  // while a step shrinks the force imbalance to at most this fraction: each load step starts
  // from the previous amplitude's tangent, factorised anyway for the adjoint. In [0, 1); 0:
  // exact Newton.
  double chord_contraction = kLoadStepChordContraction;
  // The stage's memory at most, in bytes (0: no bound): per fitted case one equilibrium solver
  // with its factorised tangent (the free body's pattern bounds every support's), the case's
  // reference, and its part in the two responses alive at a time (the line search's point and
  // its trial; GaussNewtonPoint::Idle). Generated fitted probes beyond it are left out, evenly
  // spread, before any solve (the named cases stay in), and the result counts them. >= 0.
  double max_bytes = 0.0;

  // Throws std::invalid_argument naming the field, its value and the rule.
  void Validate(const std::string& owner = "NonlinearFitOptions") const;
};

// One probe at one amplitude, with the reference's equilibrium there.
struct NonlinearCase {
  int probe = 0;  // in the bank
  double amplitude = 0.0;
  Vector reference;     // the reference's equilibrium displacement, flat d*n
  double weight = 0.0;  // in the fitted objective (0 for choosing cases)
};

// The fitted and choosing cases of a bank, the reference solved for each (in parallel on the
// pool; the same result whatever the threads). A probe the reference has no equilibrium for at
// some amplitude is left out there.
class NonlinearCases {
 public:
  // `fit_weight`: per probe, its weight in the rest-linear objective (FitWeights): the fitted
  // probes and their families' shares, which the cases keep (each family's share spread over
  // its cases, every case a relative error).
  NonlinearCases(const Problem& problem, const ProbeBank& bank,
                 const std::vector<double>& fit_weight, const NonlinearFitOptions& options,
                 Interruption* interruption = nullptr, WorkerPool* pool = nullptr);

  const Problem& problem() const { return problem_; }
  const ProbeBank& bank() const { return bank_; }
  // Ordered by probe, then by amplitude ascending.
  const std::vector<NonlinearCase>& fitted() const { return fitted_; }
  const std::vector<NonlinearCase>& choosing() const { return choosing_; }
  // The memory bound (NonlinearFitOptions::max_bytes): the bytes a fitted case holds (0 without
  // a bound) and the fitted probes it left out.
  double CaseBytes() const { return case_bytes_; }
  int LeftForMemory() const { return left_for_memory_; }

  // What the nonlinear fit chooses by: FamilyBalancedRms over the choosing probes of each
  // probe's RMS E over its amplitudes, the model solved with the spring law. A case the model
  // has no equilibrium for (a mechanism, Newton's failure), or whose equilibrium turns an
  // element of the FEM mesh inside out (InvertedElements), counts as E = 1 there (the whole
  // response missed) and in `failed`.
  // E is capped at 1 there too: a probe missed by more than its whole response (an equilibrium
  // on another branch, a snap-through) is missed, and one such probe does not decide a choice.
  double ChoosingError(const std::vector<double>& weights, int* failed = nullptr) const;

  // The fitted cases' equilibrium solvers that no NonlinearResponse holds. A solver's
  // construction orders its sparsity pattern (the candidates' on the case's support), the same
  // for every model, so the responses of successive trials hand them on; a solver's results do
  // not depend on what it solved before (EquilibriumSolver::Solve takes its start explicitly).
  std::unique_ptr<EquilibriumSolver> TakeSolver(std::size_t fitted_case) const;
  void ReturnSolvers(std::vector<std::unique_ptr<EquilibriumSolver>>& solvers) const;
  // How many solvers TakeSolver built (the rest were handed on): one per fitted case when the
  // fit keeps one set of factorised tangents alive (NonlinearResponse::Idle).
  int SolversBuilt() const { return solvers_built_.load(); }

  // Fits from the start model (NonlinearResponse::CaseErrors at it, NaN where it found no
  // stable equilibrium): a fitted case the start cannot hold (it folds there, its tangent not
  // positive definite or an FEM element inside out, or has no equilibrium: at a deep push or a
  // large load) is left out of the objective, and the later
  // amplitudes of its probe with it (each is a load step from the last), so that the fit can
  // move from the start at all; the other cases of its family share the family's weight. The
  // trials are then held to every case the start held. Each kept case's weight is scaled by
  // min(1, 1 / E^2): a case the start misses by more than its whole response weighs as one
  // missed by exactly that, so that one far-off equilibrium cannot steer the fit. Returns the
  // cases left out.
  int StartFrom(const std::vector<double>& start_errors);

 private:
  const Problem& problem_;
  const ProbeBank& bank_;
  Interruption* interruption_;
  WorkerPool* pool_;
  EquilibriumOptions solver_options_;  // load steps' (LoadStepSolverOptions), the stage's chord
  // The fitted probes within NonlinearFitOptions::max_bytes, setting case_bytes_ and
  // left_for_memory_.
  std::vector<int> FittedWithinMemory(const NonlinearFitOptions& options);

  std::vector<NonlinearCase> fitted_, choosing_;
  double case_bytes_ = 0.0;
  int left_for_memory_ = 0;
  mutable std::mutex spare_mutex_;
  mutable std::vector<std::unique_ptr<EquilibriumSolver>> spare_solvers_;  // per fitted case
  mutable std::atomic<int> solvers_built_{0};
};

// The nonlinear objective's operators at a model (spring_sensitivities.h): a part per fitted
// case, H the exact tangent of the model's energy at the case's equilibrium (each probe's
// amplitudes solved in order, each warm-started from the last). A model holds a case when it
// has an equilibrium there that is a minimum of its energy and turns no FEM element inside out
// (InvertedElements): a fold fails the case, as it fails a choosing one.
class NonlinearResponse : public SpringSensitivities {
 public:
  // `cases` and `springs` (GeneSpringsOf the problem) must outlive this object; `scale` as the
  // fit's (ProbeObjective::scale()).
  NonlinearResponse(const NonlinearCases& cases, const GeneSprings& springs, const Vector& scale,
                    Interruption* interruption = nullptr, WorkerPool* pool = nullptr);
  ~NonlinearResponse() override;
  NonlinearResponse(const NonlinearResponse&) = delete;
  NonlinearResponse& operator=(const NonlinearResponse&) = delete;

  bool At(const std::vector<double>& weights) override;
  // Hands the solvers back to the cases (a trial then takes them instead of building its own);
  // a later Solve() takes a part's solver again and factorises the tangent at its equilibrium,
  // the same factorisation At() made.
  void Idle() override;
  // Per fitted case, the relative error E of the last successful At()'s equilibrium.
  const std::vector<double>& CaseErrors() const { return case_errors_; }

 private:
  void Solve(std::size_t part, Matrix& b) const override;

  std::vector<double> case_errors_;
  const NonlinearCases* cases_;
  const GeneSprings* springs_;
  // The last At()'s springs and, per part (fitted case), its equilibrium, from which an idle
  // part's tangent is factorised again.
  ActiveSprings active_;
  std::vector<Vector> equilibria_;
  // Per part; empty entries after Idle(), taken again by Solve() (each part by one task at a
  // time: SpringSensitivities::Run).
  mutable std::vector<std::unique_ptr<EquilibriumSolver>> solvers_;
};

}  // namespace springfit::response
