#include "engine/response/probe_objective.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "engine/fit/stiffness_fit.h"
#include "engine/response/probe_evaluation.h"
#include "engine/response/response_fit.h"

namespace springfit::response {
namespace {

std::vector<bool> RoleMask(const ProbeBank& bank, ProbeRole role) {
  std::vector<bool> mask(bank.probes.size());
  for (std::size_t p = 0; p < bank.probes.size(); ++p) mask[p] = bank.probes[p].role == role;
  return mask;
}

}  // namespace

std::vector<double> FitWeights(const ProbeBank& bank, const ProbeOptions& options) {
  std::vector<int> count(kProbeFamilies, 0);
  for (const Probe& p : bank.probes)
    if (p.role == ProbeRole::kFit) ++count[static_cast<std::size_t>(p.family)];
  int generated = 0;
  for (int f = 0; f < kProbeFamilies; ++f)
    if (f != static_cast<int>(ProbeFamily::kNamed) && count[static_cast<std::size_t>(f)] > 0)
      ++generated;
  const double named_share = generated == 0 ? 1.0 : options.named_weight;
  std::vector<double> w(bank.probes.size(), 0.0);
  for (std::size_t p = 0; p < bank.probes.size(); ++p) {
    const Probe& probe = bank.probes[p];
    if (probe.role != ProbeRole::kFit || !(probe.reference_norm2 > 0.0)) continue;
    const double family_share =
        probe.family == ProbeFamily::kNamed ? named_share : (1.0 - named_share) / generated;
    w[p] = family_share / count[static_cast<std::size_t>(probe.family)] / probe.reference_norm2;
  }
  return w;
}

std::vector<double> PreferSupported(const std::vector<double>& errors,
                                    const std::vector<double>& lambda_min,
                                    const ResponseFitOptions& options) {
  const double best = *std::min_element(errors.begin(), errors.end());
  bool near = false;
  for (std::size_t i = 0; i < errors.size(); ++i)
    near |= lambda_min[i] >= options.min_lambda && errors[i] <= (1.0 + options.lambda_slack) * best;
  std::vector<double> score = errors;
  for (std::size_t i = 0; i < errors.size(); ++i)
    if (near && lambda_min[i] < options.min_lambda)
      score[i] = std::numeric_limits<double>::infinity();
  return score;
}

ProbeObjective::ProbeObjective(const Problem& problem, const ProbeBank& bank,
                               const SparseMatrix& reference_stiffness,
                               const std::vector<double>& prior, const ResponseFitOptions& options)
    : problem_(problem),
      bank_(bank),
      options_(options),
      weight_(FitWeights(bank, options.probes)),
      fit_(RoleMask(bank, ProbeRole::kFit)),
      select_(RoleMask(bank, ProbeRole::kSelect)) {
  const int m = problem.gene_count();
  const double median = MedianPositive(prior);
  scale_.resize(m);
  prior_scaled_.resize(m);
  for (int e = 0; e < m; ++e) {
    scale_[e] = std::max(prior[static_cast<std::size_t>(e)], 0.1 * median);
    prior_scaled_[e] = prior[static_cast<std::size_t>(e)] / scale_[e];
  }
  const int d = problem.dimension();
  for (const Support& support : bank.supports) {
    reference_.emplace_back(d, support.constrained);
    reference_.back().Factorize(reference_stiffness);
  }
  for (std::size_t s = 0; s < bank.supports.size(); ++s) {
    for (std::size_t p = 0; p < bank.probes.size(); ++p) {
      if (weight_[p] > 0.0 && bank.probes[p].support == static_cast<int>(s)) {
        fitted_supports_.push_back(s);
        break;
      }
    }
  }
}

double ProbeObjective::Regularization(const std::vector<double>& weights,
                                      double regularization) const {
  double r = 0.0;
  for (std::size_t g = 0; g < weights.size(); ++g) {
    const double dx = weights[g] / scale_[static_cast<Eigen::Index>(g)] -
                      prior_scaled_[static_cast<Eigen::Index>(g)];
    r += dx * dx;
  }
  return regularization * r / static_cast<double>(weights.size());
}

double ProbeObjective::Objective(const std::vector<double>& weights, double regularization) const {
  const std::vector<double> e = ProbeErrorsFor(bank_, SpringRestStiffness(problem_, weights), fit_);
  double f = 0.0;
  for (std::size_t p = 0; p < e.size(); ++p)
    if (weight_[p] > 0.0) f += weight_[p] * bank_.probes[p].reference_norm2 * e[p] * e[p];
  return f + Regularization(weights, regularization);
}

double ProbeObjective::LambdaMin(const std::vector<double>& weights) const {
  if (PresentSprings(weights) == 0) return 0.0;
  const SparseMatrix k = SpringRestStiffness(problem_, weights);
  double smallest = std::numeric_limits<double>::infinity();
  for (std::size_t s = 0; s < bank_.supports.size(); ++s) {
    if (!bank_.supports[s].user) continue;
    smallest = std::min(smallest, SmallestGeneralizedEigenvalue(k, reference_[s]));
  }
  return std::isfinite(smallest) ? smallest : 0.0;
}

double ProbeObjective::SelectError(const std::vector<double>& weights) const {
  if (PresentSprings(weights) == 0) return std::numeric_limits<double>::infinity();
  return FamilyBalancedRms(bank_,
                           ProbeErrorsFor(bank_, SpringRestStiffness(problem_, weights), select_));
}

std::vector<double> ProbeObjective::Weights(const Vector& x) const {
  std::vector<double> k(static_cast<std::size_t>(x.size()));
  for (Eigen::Index e = 0; e < x.size(); ++e) k[static_cast<std::size_t>(e)] = x[e] * scale_[e];
  const double floor = options_.dust * MedianPositive(k);
  for (double& w : k)
    if (w < floor) w = 0.0;
  return k;
}

Vector ProbeObjective::Scaled(const std::vector<double>& weights) const {
  Vector x(scale_.size());
  for (Eigen::Index e = 0; e < x.size(); ++e)
    x[e] = weights[static_cast<std::size_t>(e)] / scale_[e];
  return x;
}

}  // namespace springfit::response
