#include "engine/problem/force_balance.h"

#include <algorithm>
#include <cmath>

namespace springfit {

ForceBalance AssembleForceBalance(const Problem& problem,
                                  const std::vector<Vector>* displacements) {
  const int d = problem.dimension();
  const int genes = problem.gene_count();
  const SpringGeometry& geometry = problem.candidates();
  const Vector& rest = problem.scene().rest;
  const bool linear = problem.response() == Response::kLinear;

  // Row offsets: each load case's free coordinates, in node order.
  std::vector<Eigen::Index> row_offset;
  Eigen::Index rows = 0;
  for (const PreparedLoadCase& lc : problem.load_cases()) {
    row_offset.push_back(rows);
    rows += static_cast<Eigen::Index>(d) * problem.free_sets()[lc.free_set].count;
  }
  row_offset.push_back(rows);

  ForceBalance fb;
  fb.b = Vector::Zero(rows);
  fb.strain.assign(genes, 0.0);
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(static_cast<std::size_t>(genes) * problem.load_cases().size() * 2 * d);
  for (std::size_t k = 0; k < problem.load_cases().size(); ++k) {
    const PreparedLoadCase& lc = problem.load_cases()[k];
    const FreeNodes& free = problem.free_sets()[lc.free_set];
    const Vector& u = displacements ? (*displacements)[k] : lc.reference;
    const Vector x = rest + u;
    for (int i = 0; i < static_cast<int>(free.free_index.size()); ++i) {
      const int f = free.free_index[i];
      if (f < 0) continue;
      fb.b.segment(row_offset[k] + d * f, d) = -lc.force.segment(d * i, d);
    }
    for (int g = 0; g < genes; ++g) {
      const int c = problem.gene_candidates()[g];
      const NodePair pair = geometry.pairs[c];
      Vector sep = x.segment(d * pair.first, d) - x.segment(d * pair.second, d);
      double length = sep.norm();
      double stretch = length - geometry.rest_length[c];
      if (linear) {
        // The linearised spring pulls along its rest direction by its stretch along it.
        length = geometry.rest_length[c];
        sep = geometry.rest_separation.segment(d * c, d);
        stretch = sep.dot(u.segment(d * pair.first, d) - u.segment(d * pair.second, d)) / length;
      }
      const int fi = free.free_index[pair.first];
      const int fj = free.free_index[pair.second];
      if (fi < 0 && fj < 0) continue;  // no free node: no equation sees this spring here
      fb.strain[g] = std::max(fb.strain[g], std::abs(stretch) / geometry.rest_length[c]);
      if (stretch == 0.0 || length == 0.0) continue;
      const Vector force_on_first = (-stretch / length) * sep;  // per unit stiffness
      for (int a = 0; a < d; ++a) {
        if (fi >= 0) entries.emplace_back(row_offset[k] + d * fi + a, g, force_on_first[a]);
        if (fj >= 0) entries.emplace_back(row_offset[k] + d * fj + a, g, -force_on_first[a]);
      }
    }
  }
  fb.a.resize(rows, genes);
  fb.a.setFromTriplets(entries.begin(), entries.end());
  fb.a.makeCompressed();
  fb.row_offset = std::move(row_offset);
  return fb;
}

std::vector<bool> SeenGenes(const ForceBalance& fb, double unseen_strain) {
  std::vector<bool> seen(fb.strain.size());
  for (std::size_t g = 0; g < seen.size(); ++g) {
    seen[g] = fb.strain[g] >= unseen_strain && fb.a.col(static_cast<Eigen::Index>(g)).norm() > 0.0;
  }
  return seen;
}

}  // namespace springfit
