// Strategy `direct`: topology and per-spring stiffness from the force balance at the
// reference's equilibria (engine/problem/force_balance.h), by non-negative least squares
// (engine/linalg/nnls.h), judged afterwards by the same displacement cost as every other strategy.
//
// A spring is in the identified topology when its weight w_j exceeds its threshold
//   t_j = max(relative_threshold * (largest weight), significance * sigma_j),
// sigma_j the weight's standard error (weight_uncertainty.h). The first term is for exact
// data (an MSS reference): absent springs then come out at round-off, below 1e-11 of the
// largest weight in bench/direct_bench, true ones at their stiffness, 1e-8 of the largest on
// stiff-2d. The second is for noisy data (measured positions): an absent spring's weight is
// then noise of about sigma_j, and `significance` standard errors keep it out. Its confidence
// is (w_j - t_j) / sigma_j: how many standard errors it sits above (present) or below
// (absent) its threshold. sigma_j is computed for scenes of up to `uncertainty_max_genes`
// genes (one solve per gene) whose data is not exact; for exact data, beyond that size, or
// when columns are dependent, only the first term applies and confidences are unknown.
//
// Topology only (`known_stiffness` set: the paper's setting, every spring of the model has
// that stiffness): the weights only decide which springs are present. Noisy weights of
// present springs then gather around one value, and absent ones around 0: the threshold is
// the split of the weights into those two groups with least squared deviation (the absent
// group's centre held at 0), which needs no standard errors and is blind to the shrinking of
// noisy force-balance weights (stiffness_refinement.h). For exact data the relative floor
// applies as above. Kept springs get the known stiffness.
//
// The model must carry the loads: when the thresholded topology is a mechanism in some load
// case (noise pushed a needed spring under its threshold), springs below the threshold are
// added back in order of decreasing weight, the shortest such prefix that makes every load
// case carry (adding a spring never makes a mechanism, so its length is found by bisection).
// With per-spring stiffness a spring at weight 0, or on exact data at round-off (at most
// relative_threshold of the largest), has no stiffness the data tells from zero and is not
// tried; unseen springs come
// last, at the median identified stiffness. When even all tried springs do not carry, the
// result stays a mechanism (docs/ARCHITECTURE.md, "What a model leaves out").
//
// Loads that only prescribe displacements fix the weights up to one common factor: one weight
// is pinned (scale_pinning.h) and, for per-spring stiffness, the result scaled so that the
// median identified spring has the training stiffness.
//
// A spring no load case stretches or compresses (strain below `unseen_strain` in every case)
// has a zero column: its weight is not determined, it is left out and reported.
#pragma once
#include <optional>
#include <vector>

#include "engine/api/direct_result.h"
#include "engine/api/problem.h"
#include "engine/direct/stiffness_refinement.h"
#include "engine/linalg/nnls.h"
#include "engine/problem/cost.h"
#include "engine/problem/force_balance.h"

namespace springfit {

struct DirectOptions {
  double relative_threshold = 1e-10;  // of the largest weight; in (0, 1)
  double significance = 3.0;          // standard errors; >= 0
  int uncertainty_max_genes = 5000;
  // Data whose force balance the NNLS solution meets to this relative residual is exact
  // (an MSS reference): no standard errors, no confidences, the relative floor alone.
  double exact_data_residual = 1e-9;
  // Noisy data: refine the weights by the displacement cost (stiffness_refinement.h) before
  // the threshold; its standard errors replace the force balance's.
  bool refine = true;
  RefinementOptions refinement;
  double unseen_strain = kUnseenStrain;  // relative length change below which a spring is unseen
  // Topology only: the stiffness of every spring (> 0). nullopt: per-spring stiffness.
  std::optional<double> known_stiffness;
  bool carry_loads = true;  // add springs back until the model carries every load case
  NnlsOptions nnls;

  // Throws std::invalid_argument naming the field (nested ones too), its value and the rule.
  void Validate() const;
};

// Throws Interrupted when `interruption` stops it (checked inside every solve and loop).
DirectResult IdentifyDirect(const Problem& problem, const DirectOptions& options = {},
                            Interruption* interruption = nullptr);

}  // namespace springfit
