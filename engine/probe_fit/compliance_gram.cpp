#include "engine/probe_fit/compliance_gram.h"

namespace springfit::response {
std::vector<SpringColumn> FreeColumns(const GeneSprings& springs, const SupportSystem& support) {
  const int d = springs.dimension;
  std::vector<SpringColumn> columns(static_cast<std::size_t>(springs.size()));
  for (int e = 0; e < springs.size(); ++e) {
    SpringColumn& column = columns[static_cast<std::size_t>(e)];
    const NodePair pair = springs.pairs[static_cast<std::size_t>(e)];
    for (int side = 0; side < 2; ++side) {
      const int node = side == 0 ? pair.first : pair.second;
      const double sign = side == 0 ? -1.0 : 1.0;
      for (int a = 0; a < d; ++a) {
        const int free = support.free_index()[static_cast<std::size_t>(d * node + a)];
        if (free < 0) continue;
        column.index[column.count] = free;
        column.value[column.count] = sign * springs.directions(a, e);
        ++column.count;
      }
    }
  }
  return columns;
}

GeneSprings GeneSpringsOf(const Problem& problem) {
  const SpringGeometry& geometry = problem.candidates();
  const int d = geometry.dimension;
  GeneSprings s;
  s.dimension = d;
  const int m = problem.gene_count();
  s.directions.resize(d, m);
  for (int g = 0; g < m; ++g) {
    const int c = problem.gene_candidates()[static_cast<std::size_t>(g)];
    s.pairs.push_back(geometry.pairs[static_cast<std::size_t>(c)]);
    // rest_separation is X_i - X_j: the direction from i to j is its opposite.
    s.directions.col(g) = -geometry.rest_separation.segment(d * c, d) /
                          geometry.rest_length[static_cast<std::size_t>(c)];
  }
  return s;
}

GeneSprings Subset(const GeneSprings& springs, const std::vector<int>& genes) {
  GeneSprings s;
  s.dimension = springs.dimension;
  s.directions.resize(springs.dimension, static_cast<Eigen::Index>(genes.size()));
  for (std::size_t i = 0; i < genes.size(); ++i) {
    s.pairs.push_back(springs.pairs[static_cast<std::size_t>(genes[i])]);
    s.directions.col(static_cast<Eigen::Index>(i)) = springs.directions.col(genes[i]);
  }
  return s;
}

Vector Elongations(const GeneSprings& springs, const Vector& u) {
  const int d = springs.dimension;
  Vector delta(springs.size());
  for (int e = 0; e < springs.size(); ++e) {
    const NodePair pair = springs.pairs[static_cast<std::size_t>(e)];
    delta[e] =
        springs.directions.col(e).dot(u.segment(d * pair.second, d) - u.segment(d * pair.first, d));
  }
  return delta;
}

namespace {

// One support's part of the Gram matrix (every term on it).
Gram SupportGram(const GeneSprings& springs, const SupportSystem& support, const Matrix& C,
                 const std::vector<const GramTerm*>& mine) {
  const int m = springs.size();
  Gram part;
  part.c = Vector::Zero(m);
  const std::vector<SpringColumn> columns = FreeColumns(springs, support);
  // M = G^T C^2 G, through W = C^2 and T = W G.
  const Matrix W = C * C;
  const int n = static_cast<int>(W.rows());
  Matrix T = Matrix::Zero(n, m);
  for (int e = 0; e < m; ++e) {
    const SpringColumn& column = columns[static_cast<std::size_t>(e)];
    for (int a = 0; a < column.count; ++a) T.col(e) += column.value[a] * W.col(column.index[a]);
  }
  Matrix M(m, m);
  for (int f = 0; f < m; ++f) {
    const double* t = T.col(f).data();
    for (int e = 0; e < m; ++e) {
      const SpringColumn& column = columns[static_cast<std::size_t>(e)];
      double v = 0.0;
      for (int a = 0; a < column.count; ++a) v += column.value[a] * t[column.index[a]];
      M(e, f) = v;
    }
  }
  // P = sum_p w_p delta_p delta_p^T, and c.
  Matrix Delta(m, static_cast<Eigen::Index>(mine.size()));
  for (std::size_t p = 0; p < mine.size(); ++p) {
    const GramTerm& term = *mine[p];
    Delta.col(static_cast<Eigen::Index>(p)) = std::sqrt(term.weight) * term.elongation;
    const Vector y = C * term.target;
    Vector z(m);
    for (int e = 0; e < m; ++e) {
      const SpringColumn& column = columns[static_cast<std::size_t>(e)];
      double v = 0.0;
      for (int a = 0; a < column.count; ++a) v += column.value[a] * y[column.index[a]];
      z[e] = v;
    }
    part.c += term.weight * term.elongation.cwiseProduct(z);
    part.constant += term.weight * term.target.squaredNorm();
  }
  Matrix P(m, m);
  P.setZero();
  P.selfadjointView<Eigen::Lower>().rankUpdate(Delta);
  P.triangularView<Eigen::StrictlyUpper>() = P.transpose();
  part.H = M.cwiseProduct(P);
  return part;
}

}  // namespace

Gram BuildGram(const GeneSprings& springs, const std::vector<SupportSystem>& supports,
               const std::vector<Matrix>& compliance, const std::vector<GramTerm>& terms,
               WorkerPool* pool) {
  const int m = springs.size();
  std::vector<std::vector<const GramTerm*>> mine(supports.size());
  for (const GramTerm& term : terms) mine[static_cast<std::size_t>(term.support)].push_back(&term);
  std::vector<std::size_t> used;
  for (std::size_t s = 0; s < supports.size(); ++s)
    if (!mine[s].empty()) used.push_back(s);
  // Each support's part on its own (in parallel on the pool), summed in support order: the
  // result does not depend on the threads.
  std::vector<Gram> parts(used.size());
  const auto body = [&](int slot) {
    const std::size_t s = used[static_cast<std::size_t>(slot)];
    parts[static_cast<std::size_t>(slot)] =
        SupportGram(springs, supports[s], compliance[s], mine[s]);
  };
  RunSlots(pool, static_cast<int>(used.size()), body);
  Gram gram;
  gram.H = Matrix::Zero(m, m);
  gram.c = Vector::Zero(m);
  for (Gram& part : parts) {
    gram.H += part.H;
    gram.c += part.c;
    gram.constant += part.constant;
    part.H.resize(0, 0);
  }
  return gram;
}

}  // namespace springfit::response
