// The identification strategies behind one small interface, and the one place that maps a
// Strategy to its code.
//
//   paper    GeneticStrategy: the paper's GA (search_options.h)
//   direct   DirectStrategy: non-negative least squares on the force balance (engine/direct/)
//   hybrid      HybridStrategy: direct's topology seeds the memetic GA, on one clock
//   continuous  ContinuousStrategy: per-spring stiffness on every candidate by sensitivities,
//               then the sparsity path (engine/fit/sparsity_path.h)
//   default     ContinuousStrategy on an FEM reference (its models beat the closed-form
//               recipes; the GA's single training stiffness cannot), HybridStrategy otherwise
//               (exact recovery of an MSS reference, the fastest measured: bench/RESULTS.md)
#pragma once

#include <memory>

#include "engine/identification/identify.h"
#include "engine/identification/run_monitor.h"

namespace springfit {

class IdentificationStrategy {
 public:
  virtual ~IdentificationStrategy() = default;
  // Runs on a prepared problem. Fills the strategy's part of the result: stop, best, trace,
  // evaluation, counters, generations, wall time, stiffness when it identifies it, and its
  // own details; RunIdentification() fills the rest. Reports beats and checks for a stop
  // through `monitor`; throws Interrupted when stopped before it had any model to return.
  virtual IdentificationResult Run(const Problem& problem, const SearchOptions& options,
                                   const RunContext& context, RunMonitor& monitor) const = 0;
};

// The genetic algorithm as the options configure it (paper, or the memetic GA alone).
class GeneticStrategy : public IdentificationStrategy {
 public:
  IdentificationResult Run(const Problem& problem, const SearchOptions& options,
                           const RunContext& context, RunMonitor& monitor) const override;
};

class DirectStrategy : public IdentificationStrategy {
 public:
  IdentificationResult Run(const Problem& problem, const SearchOptions& options,
                           const RunContext& context, RunMonitor& monitor) const override;
};

// Direct (topology only, at the training stiffness), then the GA seeded with its topology,
// the direct phase's time starting the GA's clock. A resumed run does not run the direct phase
// again: it reports it from the checkpoint's seed.
class HybridStrategy : public IdentificationStrategy {
 public:
  IdentificationResult Run(const Problem& problem, const SearchOptions& options,
                           const RunContext& context, RunMonitor& monitor) const override;
};

// Runs the sparsity path from the closed-form baseline (FEM reference) or from the training
// stiffness on every candidate (otherwise), returns the chosen point refitted to convergence,
// and its held-out error. Identifies topology and stiffness; its trace follows the first fit
// (rows after accepted steps 1, 2, 4, 8, ... and at its end: the lowest error so far).
class ContinuousStrategy : public IdentificationStrategy {
 public:
  IdentificationResult Run(const Problem& problem, const SearchOptions& options,
                           const RunContext& context, RunMonitor& monitor) const override;
};

// The run's threads: the caller's pool, else one of context.threads kept in `own` (none for
// one thread).
WorkerPool* PoolOf(const RunContext& context, std::unique_ptr<WorkerPool>& own);

// Strategy continuous fits the reference's whole response (probe_fit_strategy.cpp) when the
// reference can be probed (FEM or MSS), the probes are not switched off and no target error is
// set (it chooses along the named cases' path), by the matrix-free fit (matrix_free_fit.h).
bool FitsToProbes(const Problem& problem, const SearchOptions& options);
// A model certified on the probe bank: the model returned (the one given, or the closed-form
// baseline when the given one is not better on the choosing probes), and its certificate.
struct ProbeCertificate {
  std::vector<double> weights;
  bool returned_baseline = false;
  response::Generalization generalization;
  bool judgement_stopped = false;  // the amplitudes are then empty
};
// The baseline guarantee and the certificate of a model (per-gene weights) on the probe bank,
// when the reference can be probed and the probes are not switched off; `start` is the
// baseline's stand-in for an MSS reference. Throws Interrupted when stopped before the
// certificate is made.
std::optional<ProbeCertificate> CertifyOnProbes(const Problem& problem,
                                                const SearchOptions& options,
                                                const std::vector<double>& weights,
                                                const std::vector<double>& start,
                                                Interruption* interruption = nullptr,
                                                WorkerPool* pool = nullptr);
IdentificationResult RunProbeFit(const Problem& problem, const SearchOptions& options,
                                 const RunContext& context, RunMonitor& monitor);
// Strategy continuous fitted to the named cases' sparsity path (named_case_fit.cpp), where it
// does not fit to probes.
IdentificationResult RunNamedCaseFit(const Problem& problem, const SearchOptions& options,
                                     const RunContext& context, RunMonitor& monitor);

std::unique_ptr<IdentificationStrategy> MakeStrategy(Strategy strategy, const Problem& problem);

}  // namespace springfit
