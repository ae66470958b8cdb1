#include "engine/problem/rest_stiffness.h"

#include "engine/fem/fem_model.h"

namespace springfit {
namespace {

using Triplets = std::vector<Eigen::Triplet<double>>;

// k n n^T on the four blocks of (i, j).
void AddSpring(int d, int i, int j, const Vector& direction, double k, Triplets& t) {
  for (int a = 0; a < d; ++a) {
    for (int b = 0; b < d; ++b) {
      const double v = k * direction[a] * direction[b];
      t.emplace_back(d * i + a, d * i + b, v);
      t.emplace_back(d * j + a, d * j + b, v);
      t.emplace_back(d * i + a, d * j + b, -v);
      t.emplace_back(d * j + a, d * i + b, -v);
    }
  }
}

template <int D>
void AddElements(const std::vector<fem::Element<D>>& elements,
                 const std::vector<fem::MaterialLaw<D>>& laws, Triplets& t) {
  const MatD<D> at_rest = MatD<D>::Zero();
  for (const fem::Element<D>& element : elements) {
    const auto response = laws[static_cast<std::size_t>(element.law)].Evaluate(at_rest, true);
    for (int a = 0; a <= D; ++a) {
      for (int b = 0; b <= D; ++b) {
        // K_ab(i, k) = V0 sum_JL A(i + D J, k + D L) G_aJ G_bL
        for (int i = 0; i < D; ++i) {
          for (int k = 0; k < D; ++k) {
            double v = 0.0;
            for (int J = 0; J < D; ++J)
              for (int L = 0; L < D; ++L)
                v += response.tangent(i + D * J, k + D * L) * element.gradients(a, J) *
                     element.gradients(b, L);
            t.emplace_back(D * element.nodes[a] + i, D * element.nodes[b] + k, element.volume * v);
          }
        }
      }
    }
  }
}

SparseMatrix FromTriplets(int size, const Triplets& t) {
  SparseMatrix k(size, size);
  k.setFromTriplets(t.begin(), t.end());
  return k;
}

}  // namespace

SparseMatrix ReferenceRestStiffness(const Problem& problem) {
  const Scene& scene = problem.scene();
  const int d = scene.dimension;
  if (scene.reference.kind == Reference::Kind::kFem) {
    const fem::FemModel model = fem::FemModel::Build(scene);
    Triplets t;
    if (d == 2)
      AddElements<2>(model.elements2(), model.laws2(), t);
    else
      AddElements<3>(model.elements3(), model.laws3(), t);
    return FromTriplets(static_cast<int>(model.rest().size()), t);
  }
  const Reference& reference = scene.reference;
  std::vector<double> stiffness(reference.springs.size(), 1.0);
  for (std::size_t s = 0; s < reference.springs.size(); ++s) {
    if (reference.stiffness.size() == reference.springs.size())
      stiffness[s] = reference.stiffness[s];
    else if (!reference.stiffness.empty())
      stiffness[s] = reference.stiffness[0];
  }
  return SpringRestStiffness(d, scene.rest, reference.springs, stiffness);
}

SparseMatrix SpringRestStiffness(const Problem& problem, const std::vector<double>& weights) {
  const SpringGeometry& geometry = problem.candidates();
  const int d = geometry.dimension;
  Triplets t;
  const std::vector<int>& gene_candidate = problem.gene_candidates();
  for (std::size_t g = 0; g < weights.size(); ++g) {
    if (weights[g] <= 0.0) continue;
    const int c = gene_candidate[g];
    const NodePair pair = geometry.pairs[static_cast<std::size_t>(c)];
    const Vector direction = geometry.rest_separation.segment(d * c, d) /
                             geometry.rest_length[static_cast<std::size_t>(c)];
    AddSpring(d, pair.first, pair.second, direction, weights[g], t);
  }
  // The springs no load case sees, with the problem's stiffness for them: part of every model.
  const std::vector<int>& unseen = problem.unidentifiable();
  for (std::size_t u = 0; u < unseen.size(); ++u) {
    const int c = unseen[u];
    const NodePair pair = geometry.pairs[static_cast<std::size_t>(c)];
    const Vector direction = geometry.rest_separation.segment(d * c, d) /
                             geometry.rest_length[static_cast<std::size_t>(c)];
    AddSpring(d, pair.first, pair.second, direction, problem.unidentifiable_stiffness()[u], t);
  }
  return FromTriplets(static_cast<int>(problem.scene().rest.size()), t);
}

SparseMatrix SpringRestStiffness(int dimension, const Vector& rest,
                                 const std::vector<NodePair>& springs,
                                 const std::vector<double>& stiffness) {
  const int d = dimension;
  Triplets t;
  for (std::size_t s = 0; s < springs.size(); ++s) {
    const NodePair pair = springs[s];
    Vector direction = rest.segment(d * pair.second, d) - rest.segment(d * pair.first, d);
    direction /= direction.norm();
    AddSpring(d, pair.first, pair.second, direction, stiffness[s], t);
  }
  return FromTriplets(static_cast<int>(rest.size()), t);
}

}  // namespace springfit
