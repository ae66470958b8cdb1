// What every probe fit judges a model by (response_fit.h): the fitted objective, the choosing
// error, the smallest generalised eigenvalue, the choices among candidate models, and the scaled
// variables the fits work in: the rest-linear fit, its nonlinear stage, the soft-mode rounds and
// the lift all choose by the same numbers.
#pragma once

#include <limits>
#include <vector>

#include "engine/probe_fit/probe_bank.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/problem/support_system.h"

namespace springfit::response {

struct ResponseFitOptions;

// The choosing error of no model (a mechanism, no springs).
inline constexpr double kNoModel = std::numeric_limits<double>::infinity();

// Per probe, its weight in the fitted objective: the named cases share `named_weight`, the
// soft-mode probes `soft_mode_weight` (when there are any), the generated families present in
// the fit share the rest equally, and within a family every
// probe counts alike as a relative error (1 / |u_ref|^2). Probes not fitted weigh 0.
std::vector<double> FitWeights(const ProbeBank& bank, const ProbeOptions& options);

// The fits work in scaled variables x = k / scale, scale = the prior stiffness (at least a tenth
// of its median), so that a fit does not depend on units and the Tikhonov pull moves every
// spring by its own prior alike.
Vector PriorScale(const std::vector<double>& prior);

// `weights` with the springs below the largest / max_spread removed (ResponseFitOptions::
// max_spread; 0: unchanged).
std::vector<double> BoundSpread(std::vector<double> weights, double max_spread);

// FamilyBalancedRms on the bank's choosing probes: what every choice between models goes by.
// `factorized` as for ProbeErrorsFor.
double ChoosingError(const ProbeBank& bank, const SparseMatrix& model,
                     Interruption* interruption = nullptr, const FactorizedOn& factorized = {});

class ProbeObjective {
 public:
  // Factorises the reference on every support of the bank. `interruption`, when set, stops the
  // judgements below between solves (they throw Interrupted): at 10,000 nodes one takes
  // seconds.
  ProbeObjective(const Problem& problem, const ProbeBank& bank,
                 const SparseMatrix& reference_stiffness, const std::vector<double>& prior,
                 const ResponseFitOptions& options, Interruption* interruption = nullptr);

  // The exact fitted objective: weighted mean squared relative error plus the regularisation
  // (`regularization` / genes per unit of squared scaled distance from the prior).
  double Objective(const std::vector<double>& weights, double regularization) const;
  // The regularisation term alone.
  double Regularization(const std::vector<double>& weights, double regularization) const;
  // The smallest generalised eigenvalue of (K_model, K_ref) over the user supports.
  // `factorized`: the model's factorisations the caller already holds (probe_evaluation.h).
  double LambdaMin(const std::vector<double>& weights, const FactorizedOn& factorized = {}) const;
  // The same, and the soft modes below `below` (at most `count` per user support) from the same
  // Lanczos runs, in support order: one run for both (at 10,000 nodes each is seconds).
  struct SupportMode {
    std::size_t support = 0;
    SoftMode mode;
  };
  double LambdaMinAndSoftModes(const std::vector<double>& weights, const FactorizedOn& factorized,
                               double below, int count, std::vector<SupportMode>& soft) const;
  // FamilyBalancedRms on the choosing probes; infinity for no model.
  double SelectError(const std::vector<double>& weights, const FactorizedOn& factorized = {}) const;

  // Per-gene weights of scaled variables, with the dust (below options.dust of the median)
  // removed; and back.
  std::vector<double> Weights(const Vector& x) const;
  Vector Scaled(const std::vector<double>& weights) const;

  const Problem& problem() const { return problem_; }
  const ProbeBank& bank() const { return bank_; }
  const std::vector<double>& weight() const { return weight_; }  // per probe (FitWeights)
  const Vector& scale() const { return scale_; }
  const Vector& prior_scaled() const { return prior_scaled_; }
  // Per support of the bank, the reference's system, factorised on the user's supports and
  // those with a probe of the bank (the held-out pushes' own are not: the certificate's).
  const std::vector<SupportSystem>& reference() const { return reference_; }
  // The supports with a fitted probe, ascending.
  const std::vector<std::size_t>& fitted_supports() const { return fitted_supports_; }

 private:
  const Problem& problem_;
  const ProbeBank& bank_;
  const ResponseFitOptions& options_;
  Interruption* interruption_;
  std::vector<double> weight_;
  std::vector<bool> fit_;
  std::vector<SupportSystem> reference_;
  std::vector<std::size_t> fitted_supports_;
  Vector scale_, prior_scaled_;
};

}  // namespace springfit::response
