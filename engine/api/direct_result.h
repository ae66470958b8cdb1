// The engine's public surface (engine/api/). What strategy `direct` returns
// (engine/direct/direct_identification.h): its weights, topology, standard
// errors and the identified model, apart from the machinery that computes them.
#pragma once

#include <vector>

#include "engine/api/model.h"
#include "engine/api/problem.h"
#include "engine/linalg/nnls_result.h"

namespace springfit {

struct DirectResult {
  std::vector<double> weights;  // per gene, >= 0; 0 for unseen genes
  Genome genome;                // genes whose weight is above the threshold
  std::vector<int> unseen;      // genes no load case can see
  // Per gene (empty when not computed): the weight's standard error, and its confidence
  // (w - threshold) / sigma; NaN for unseen genes.
  std::vector<double> sigma;
  std::vector<double> confidence;
  // Topology only, noisy data: the weight splitting present from absent springs (0 otherwise).
  double topology_threshold = 0.0;
  // The loads only prescribe displacements (no external force on a free node): the data fix
  // the weights up to one factor. Gene `pinned_gene` was held at weight 1 and the others
  // solved relative to it (scale_pinning.h); the weights (and per-spring stiffness) are then
  // scaled so that the median identified spring has the training (or known) stiffness.
  bool displacement_only = false;
  int pinned_gene = -1;
  // Genes below their threshold added back so that the model carries the loads.
  std::vector<int> added_to_carry;
  // The identified model: candidate indices and stiffness (the weight, or the known stiffness).
  ActiveSprings springs;
  // |A w - b| / |b| for the identified model's weights (thresholded), and of the NNLS
  // solution itself: how well the force balance holds.
  double force_residual = 0.0;
  double nnls_residual = 0.0;
  NnlsResult nnls;
  bool refined = false;           // the weights are the displacement-cost fit's
  int refinement_iterations = 0;  // its accepted steps, whether or not its reading was kept
  int evaluations = 0;            // of the displacement cost (readings and the load-carrying guard)
  Evaluation evaluation;          // the identified model's equilibria against the reference
  double assemble_seconds = 0.0;
  double solve_seconds = 0.0;
  double evaluate_seconds = 0.0;
};

}  // namespace springfit
