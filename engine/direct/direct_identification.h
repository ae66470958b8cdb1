// Strategy `direct`: topology and per-spring stiffness from the force balance at the
// reference's equilibria (force_balance.h), by non-negative least squares (nnls.h), judged
// afterwards by the same displacement cost as every other strategy.
//
// The topology is the set of springs whose weight exceeds `relative_threshold` times the
// largest weight: an MSS reference gives the true weights up to rounding (about 1e-12 of the
// largest), absent springs 0 up to rounding, so any threshold between those works; 1e-4
// leaves room for stiffness spread over four decades. A spring no load case stretches or
// compresses (strain below `unseen_strain` in every case) has a zero column: its weight is
// not determined, it is left out and reported.
#pragma once
#include <vector>

#include "engine/cost.h"
#include "engine/direct/nnls.h"
#include "engine/problem.h"

namespace springfit {

struct DirectOptions {
  double relative_threshold = 1e-10;  // of the largest weight; in (0, 1)
  double unseen_strain = 1e-12;      // relative length change below which a spring is unseen
  NnlsOptions nnls;
};

struct DirectResult {
  std::vector<double> weights;  // per gene, >= 0; 0 for unseen genes
  Genome genome;                // genes whose weight is above the threshold
  std::vector<int> unseen;      // genes no load case can see
  ActiveSprings springs;        // the identified model: candidate indices and stiffness (= weight)
  // |A w - b| / |b| for the identified model's weights (thresholded), and of the NNLS
  // solution itself: how well the force balance holds.
  double force_residual = 0.0;
  double nnls_residual = 0.0;
  NnlsResult nnls;
  Evaluation evaluation;        // the identified model's equilibria against the reference
  double assemble_seconds = 0.0;
  double solve_seconds = 0.0;
  double evaluate_seconds = 0.0;
};

DirectResult IdentifyDirect(const Problem& problem, const DirectOptions& options = {});

}  // namespace springfit
