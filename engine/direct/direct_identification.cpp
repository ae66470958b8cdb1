#include "engine/direct/direct_identification.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "engine/direct/scale_pinning.h"
#include "engine/direct/weight_uncertainty.h"
#include "engine/genome/gene_weights.h"
#include "engine/runtime/options_check.h"
#include "engine/runtime/wall_clock.h"

namespace springfit {
namespace {

// The threshold splitting `weights` into an absent group, scored by its squared distance
// from 0, and a present group, scored by its squared deviation from its mean, with the least
// total: midway between the largest absent and the smallest present weight.
double TwoGroupThreshold(std::vector<double> weights) {
  if (weights.empty()) return 0.0;
  std::sort(weights.begin(), weights.end());
  const auto n = weights.size();
  double sum = 0.0;
  double squares = 0.0;
  for (double w : weights) {
    sum += w;
    squares += w * w;
  }
  // Split i: weights[0, i) absent, [i, n) present. The absent cost (their squares) and the
  // present one (their squares minus their sum squared over their count) add up to all the
  // squares minus the present sum squared over the present count.
  std::size_t best = n;
  double best_cost = squares;
  double below_sum = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double above_sum = sum - below_sum;
    const double split_cost = squares - above_sum * above_sum / static_cast<double>(n - i);
    if (split_cost < best_cost) {
      best_cost = split_cost;
      best = i;
    }
    below_sum += weights[i];
  }
  if (best == n) return weights.back();
  if (best == 0) return weights.front() / 2.0;
  return (weights[best - 1] + weights[best]) / 2.0;
}

// One way of reading the weights: thresholded, completed to carry the loads, evaluated.
struct Reading {
  std::vector<double> weights;
  std::optional<Vector> sigma;
  double topology_threshold = 0.0;
  Genome genome;
  std::vector<double> confidence;
  std::vector<int> added_to_carry;
  ActiveSprings springs;
  Evaluation evaluation;
};

class WeightReader {
 public:
  WeightReader(const Problem& problem, const std::vector<bool>& usable,
               const DirectOptions& options, bool exact_data, Interruption* interruption)
      : problem_(problem),
        usable_(usable),
        options_(options),
        exact_data_(exact_data),
        cost_(problem) {
    cost_.set_interruption(interruption);
  }

  Reading Read(std::vector<double> weights, std::optional<Vector> sigma) {
    Reading r;
    r.weights = std::move(weights);
    r.sigma = std::move(sigma);
    Threshold(r);
    r.springs = ModelOf(r.genome, r.weights);
    r.evaluation = Evaluate(r.springs);
    if (options_.carry_loads && r.evaluation.mechanism) CarryLoads(r);
    return r;
  }

  int evaluations() const { return evaluations_; }  // of the displacement cost, so far

 private:
  bool TopologyOnly() const { return options_.known_stiffness.has_value(); }

  void Threshold(Reading& r) const {
    const int genes = problem_.gene_count();
    const double largest = genes > 0 ? *std::max_element(r.weights.begin(), r.weights.end()) : 0.0;
    const double floor = options_.relative_threshold * largest;
    if (TopologyOnly() && !exact_data_) {
      std::vector<double> seen;
      for (int g = 0; g < genes; ++g) {
        if (usable_[g]) seen.push_back(r.weights[g]);
      }
      r.topology_threshold = TwoGroupThreshold(std::move(seen));
    }
    if (r.sigma) r.confidence.assign(genes, std::numeric_limits<double>::quiet_NaN());
    r.genome.assign(genes, 0);
    for (int g = 0; g < genes; ++g) {
      if (!usable_[g]) continue;
      double threshold = std::max(floor, r.topology_threshold);
      if (r.sigma) {
        const double s = (*r.sigma)[g];
        if (!TopologyOnly()) threshold = std::max(floor, options_.significance * s);
        r.confidence[g] = s > 0.0 ? (r.weights[g] - threshold) / s
                                  : (r.weights[g] > threshold ? HUGE_VAL : -HUGE_VAL);
      }
      if (largest > 0.0 && r.weights[g] > threshold) r.genome[g] = 1;
    }
  }

  // The genome's springs, at the known stiffness or at their weights.
  ActiveSprings ModelOf(const Genome& genome, const std::vector<double>& weights) const {
    std::vector<double> stiffness(genome.size(), 0.0);
    for (std::size_t g = 0; g < genome.size(); ++g) {
      if (genome[g]) stiffness[g] = TopologyOnly() ? *options_.known_stiffness : weights[g];
    }
    return problem_.SpringsOfWeights(stiffness);
  }

  Evaluation Evaluate(const ActiveSprings& springs) {
    ++evaluations_;
    Evaluation e = cost_.Evaluate(springs);
    if (e.interrupted) throw Interrupted();
    return e;
  }

  // Below-threshold genes by decreasing weight, then the unseen ones: the shortest prefix that
  // carries the loads. With per-spring stiffness a gene at weight 0, or on exact data at
  // round-off (at most relative_threshold of the largest), has no stiffness the data tells from
  // zero and is not tried (docs/ARCHITECTURE.md, "What a model leaves out": round-off springs
  // holding a mechanism would be a model of dust; on noisy data the floor is not what separates
  // noise); with a known stiffness every gene has one.
  // An unseen gene (no load case stretches it) can still be the one that holds a mode the loads
  // do not excite: tried last, at the median identified stiffness (the loads cannot tell its
  // own; with a known stiffness, at that).
  void CarryLoads(Reading& r) {
    const int genes = problem_.gene_count();
    const double floor =
        exact_data_ && genes > 0
            ? options_.relative_threshold * *std::max_element(r.weights.begin(), r.weights.end())
            : 0.0;
    std::vector<int> order;
    for (int g = 0; g < genes; ++g) {
      if (usable_[g] && !r.genome[g] && (r.weights[g] > floor || TopologyOnly()))
        order.push_back(g);
    }
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return r.weights[a] > r.weights[b]; });
    std::vector<double> weights = r.weights;
    std::vector<double> present(genes, 0.0);
    for (int g = 0; g < genes; ++g)
      if (r.genome[g]) present[g] = r.weights[g];
    if (std::any_of(present.begin(), present.end(), [](double w) { return w > 0.0; })) {
      const double stand_in = MedianPositive(present);
      for (int g = 0; g < genes; ++g) {
        if (usable_[g]) continue;
        order.push_back(g);
        weights[g] = stand_in;
      }
    }
    const auto with_prefix = [&](std::size_t count) {
      Genome genome = r.genome;
      for (std::size_t i = 0; i < count; ++i) genome[order[i]] = 1;
      return genome;
    };
    const auto carries = [&](std::size_t count) {
      return !Evaluate(ModelOf(with_prefix(count), weights)).mechanism;
    };
    if (!carries(order.size())) return;
    std::size_t enough = order.size();
    std::size_t too_few = 0;
    while (enough - too_few > 1) {
      const std::size_t mid = too_few + (enough - too_few) / 2;
      (carries(mid) ? enough : too_few) = mid;
    }
    r.added_to_carry.assign(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(enough));
    std::sort(r.added_to_carry.begin(), r.added_to_carry.end());
    r.genome = with_prefix(enough);
    r.springs = ModelOf(r.genome, weights);
    r.evaluation = Evaluate(r.springs);
  }

  const Problem& problem_;
  const std::vector<bool>& usable_;
  const DirectOptions& options_;
  bool exact_data_;
  CostFunction cost_;
  int evaluations_ = 0;
};

}  // namespace

void DirectOptions::Validate() const {
  const OptionsCheck check("DirectOptions");
  check.Require(InOpenUnit(relative_threshold), "relative_threshold", relative_threshold,
                "0 < value < 1");
  check.Require(significance >= 0.0 && std::isfinite(significance), "significance", significance,
                "0 <= value < infinity");
  check.Require(uncertainty_max_genes >= 0, "uncertainty_max_genes", uncertainty_max_genes,
                "value >= 0");
  check.Require(InOpenUnit(exact_data_residual), "exact_data_residual", exact_data_residual,
                "0 < value < 1");
  check.Require(InOpenUnit(unseen_strain), "unseen_strain", unseen_strain, "0 < value < 1");
  if (known_stiffness) {
    check.Require(*known_stiffness > 0.0 && std::isfinite(*known_stiffness), "known_stiffness",
                  *known_stiffness, "0 < value < infinity");
  }
  refinement.Validate(check.Nested("refinement"));
  nnls.Validate(check.Nested("nnls"));
}

namespace {

// The weights the force balance gives (NNLS), and what reading them needs.
struct SolvedWeights {
  std::vector<double> weights;  // per gene; the pinned gene at 1
  Vector rhs;                   // of the system solved: the force balance's, or its pinned form
  std::vector<bool> columns;    // the columns it was solved over
  double variance = 0.0;        // of the residual, over the degrees of freedom left
  bool exact_data = false;      // the force balance holds to round-off (an MSS reference)
  std::optional<RefinementResult> refinement;
};

// NNLS on the force balance (its pinned form when the loads only prescribe displacements,
// scale_pinning.h), then, on data that are not exact, the weights refined against the
// displacements.
SolvedWeights SolveWeights(const Problem& problem, const ForceBalance& fb,
                           const std::vector<bool>& usable, const DirectOptions& options,
                           Interruption* interruption, DirectResult& r) {
  SolvedWeights solved;
  solved.rhs = fb.b;
  solved.columns = usable;
  r.displacement_only = problem.DisplacementOnly();
  std::optional<PinnedSolution> pinned;
  if (r.displacement_only) pinned = SolvePinnedNnls(fb.a, usable, {}, options.nnls, interruption);
  if (pinned) {
    r.pinned_gene = pinned->pinned_gene;
    r.nnls = std::move(pinned->nnls);
    solved.rhs = std::move(pinned->rhs);
    solved.columns = std::move(pinned->columns);
  } else {
    r.nnls = SolveNnls(fb.a, fb.b, usable, options.nnls, interruption);
  }
  solved.weights.assign(r.nnls.x.data(), r.nnls.x.data() + r.nnls.x.size());
  if (r.pinned_gene >= 0) solved.weights[r.pinned_gene] = 1.0;
  // The residual variance over the degrees of freedom left by the positive weights.
  int positive = 0;
  for (const double w : solved.weights) positive += w > 0.0;
  const double dof = std::max<double>(static_cast<double>(fb.a.rows()) - positive, 1.0);
  solved.variance = (fb.a * r.nnls.x - solved.rhs).squaredNorm() / dof;
  // Exact data (an MSS reference: the force balance holds to round-off) needs no standard
  // errors: its absent springs sit at round-off, below the relative floor. They would cost
  // one solve per gene, several times the identification itself.
  const double rhs_norm = std::max(solved.rhs.norm(), 1e-300);
  solved.exact_data =
      (fb.a * r.nnls.x - solved.rhs).norm() <= options.exact_data_residual * rhs_norm;
  r.nnls_residual = (fb.a * r.nnls.x - solved.rhs).norm() / rhs_norm;
  if (!solved.exact_data && options.refine) {
    solved.refinement =
        RefineWeights(problem, solved.weights, usable, options.refinement, interruption);
    if (!solved.refinement->refined) solved.refinement.reset();
  }
  if (solved.refinement) r.refinement_iterations = solved.refinement->iterations;
  return solved;
}

// The topology read off the weights (WeightReader: the threshold, the springs kept to carry
// the loads, the evaluation), the refined weights' reading kept where it fits better.
void ReadWeights(const Problem& problem, const ForceBalance& fb, const std::vector<bool>& usable,
                 const DirectOptions& options, Interruption* interruption, SolvedWeights solved,
                 DirectResult& r) {
  WeightReader reader(problem, usable, options, solved.exact_data, interruption);
  // Noisy data never go without standard errors when they can be had: the relative floor
  // alone lets every spurious weight in.
  std::optional<Vector> nnls_sigma;
  if (!solved.exact_data)
    nnls_sigma = WeightStandardErrors(fb.a, solved.columns, solved.variance,
                                      options.uncertainty_max_genes, interruption);
  if (nnls_sigma && r.pinned_gene >= 0) (*nnls_sigma)[r.pinned_gene] = 0.0;  // fixed, not estimated
  Reading reading = reader.Read(std::move(solved.weights), std::move(nnls_sigma));
  if (solved.refinement) {
    // The refined weights fit the displacements, but from a poor start the fit can drift to
    // a worse topology than the force balance's: the lower displacement cost decides.
    std::optional<Vector> sigma;
    if (!solved.refinement->sigma.empty())
      sigma = Eigen::Map<const Vector>(solved.refinement->sigma.data(), problem.gene_count());
    if (!sigma) sigma = reading.sigma;
    Reading refined = reader.Read(solved.refinement->weights, std::move(sigma));
    if (!(reading.evaluation.cost < refined.evaluation.cost)) {
      reading = std::move(refined);
      r.refined = true;
    }
  }
  r.weights = std::move(reading.weights);
  if (reading.sigma)
    r.sigma.assign(reading.sigma->data(), reading.sigma->data() + reading.sigma->size());
  r.confidence = std::move(reading.confidence);
  r.topology_threshold = reading.topology_threshold;
  r.genome = std::move(reading.genome);
  r.added_to_carry = std::move(reading.added_to_carry);
  r.springs = std::move(reading.springs);
  r.evaluation = std::move(reading.evaluation);
  r.evaluations = reader.evaluations();
}

// Only ratios of stiffness are in the data when the loads only prescribe displacements: the
// weights are scaled so that the median kept spring has the training stiffness (the known one
// for topology only, which the springs have anyway). The equilibria, hence the evaluation, do
// not change.
void FixDisplacementOnlyScale(const Problem& problem, const DirectOptions& options,
                              DirectResult& r) {
  std::vector<double> kept_weights(problem.gene_count(), 0.0);
  bool any_kept = false;
  for (int g = 0; g < problem.gene_count(); ++g) {
    if (r.genome[g] && r.weights[g] > 0.0) {
      kept_weights[g] = r.weights[g];
      any_kept = true;
    }
  }
  if (!r.displacement_only || !any_kept) return;
  const double factor =
      options.known_stiffness.value_or(problem.training_stiffness()) / MedianPositive(kept_weights);
  for (double& w : r.weights) w *= factor;
  for (double& s : r.sigma) s *= factor;
  r.topology_threshold *= factor;
  if (!options.known_stiffness) {
    for (double& k : r.springs.stiffness) k *= factor;
  }
}

// The kept springs' force imbalance, relative to the external forces; with none, to the spring
// forces themselves.
double ForceResidual(const ForceBalance& fb, int genes, const DirectResult& r) {
  Vector kept = Vector::Zero(genes);
  for (std::size_t i = 0, g = 0; g < static_cast<std::size_t>(genes); ++g) {
    if (r.genome[g]) kept[static_cast<Eigen::Index>(g)] = r.springs.stiffness[i++];
  }
  const double force_scale =
      r.displacement_only ? SparseMatrix(fb.a * kept.asDiagonal()).norm() : fb.b.norm();
  return (fb.a * kept - fb.b).norm() / std::max(force_scale, 1e-300);
}

}  // namespace

DirectResult IdentifyDirect(const Problem& problem, const DirectOptions& options,
                            Interruption* interruption) {
  options.Validate();
  DirectResult r;
  auto start = std::chrono::steady_clock::now();
  const ForceBalance fb = AssembleForceBalance(problem);
  const std::vector<bool> usable = SeenGenes(fb, options.unseen_strain);
  for (int g = 0; g < problem.gene_count(); ++g) {
    if (!usable[g]) r.unseen.push_back(g);
  }
  r.assemble_seconds = SecondsSince(start);

  start = std::chrono::steady_clock::now();
  SolvedWeights solved = SolveWeights(problem, fb, usable, options, interruption, r);
  r.solve_seconds = SecondsSince(start);

  start = std::chrono::steady_clock::now();
  ReadWeights(problem, fb, usable, options, interruption, std::move(solved), r);
  FixDisplacementOnlyScale(problem, options, r);
  r.force_residual = ForceResidual(fb, problem.gene_count(), r);
  r.evaluate_seconds = SecondsSince(start);
  return r;
}

}  // namespace springfit
