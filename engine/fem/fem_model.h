// A finite-element model on a scene's nodes, ready to evaluate: per element its nodes, the
// gradients of its linear shape functions at rest, its rest volume (area x thickness in 2D)
// and its material law.
//
// With x = X + u the deformed positions and G_a the rest gradient of node a's shape function,
// an element's deformation gradient is F = sum_a x_a G_a^T (constant over a linear simplex),
// its energy V0 W(F), the force it puts on node a is f_a = -V0 P G_a, and the stiffness block
// between nodes a and b is K_ab(i, k) = V0 sum_JL A_iJkL G_aJ G_bL (material_law.h).
// The potential energy of a load case is sum_e V0 W(F_e) - f . u.
//
// Immutable after Build(); safe to share between threads.
#pragma once

#include <algorithm>
#include <array>
#include <vector>

#include "engine/api/scene.h"
#include "engine/fem/material_law.h"

namespace springfit::fem {

template <int D>
struct Element {
  std::array<int, D + 1> nodes{};
  Eigen::Matrix<double, D + 1, D> gradients;  // row a: G_a^T
  double volume = 0.0;                        // V0 (2D: area x thickness)
  int law = 0;                                // index into FemModel's laws
};

// Calls visit(element, facet, opposite) for every facet of every element of `fem`: the edges
// of triangles, the faces of tetrahedra, `facet` its d node indices ascending and `opposite`
// the element's remaining node.
template <typename Visit>
void ForEachFacet(const FemReference& fem, int dimension, Visit&& visit) {
  std::vector<int> facet;
  for (std::size_t e = 0; e < fem.elements.size(); ++e) {
    const std::vector<int>& element = fem.elements[e];
    for (int skip = 0; skip <= dimension; ++skip) {
      facet.clear();
      for (int a = 0; a <= dimension; ++a) {
        if (a != skip) facet.push_back(element[a]);
      }
      std::sort(facet.begin(), facet.end());
      visit(e, facet, element[skip]);
    }
  }
}

// H = F - I = sum_a u_a G_a^T of an element at displacement u (flat d*n).
template <int D>
MatD<D> DisplacementGradient(const Element<D>& element, const Vector& u) {
  MatD<D> h = MatD<D>::Zero();
  for (int a = 0; a <= D; ++a)
    h += u.template segment<D>(D * element.nodes[a]) * element.gradients.row(a);
  return h;
}

class FemModel {
 public:
  FemModel() = default;
  // Precondition: the scene passed ValidateScene (its reference is kFem, elements are
  // non-degenerate and in range).
  static FemModel Build(const Scene& scene);

  int dimension() const { return dimension_; }
  int node_count() const { return node_count_; }
  int element_count() const {
    return dimension_ == 2 ? static_cast<int>(elements2_.size())
                           : static_cast<int>(elements3_.size());
  }
  const Vector& rest() const { return rest_; }
  const std::vector<Element<2>>& elements2() const { return elements2_; }
  const std::vector<Element<3>>& elements3() const { return elements3_; }
  const std::vector<MaterialLaw<2>>& laws2() const { return laws2_; }
  const std::vector<MaterialLaw<3>>& laws3() const { return laws3_; }
  // Whether every material is linear: the energy is then quadratic in u.
  bool linear() const { return linear_; }

  // The deformation gradient's determinant of element e at displacement u (flat d*n).
  double Jacobian(int e, const Vector& u) const;
  // The first element with J <= 0 at u, or -1.
  int FirstInvertedElement(const Vector& u) const;
  // Per element, its largest principal Green-Lagrange strain in magnitude,
  // E = (H + H^T + H^T H) / 2, at displacement u (flat d*n); unit-free. The Green-Lagrange rather
  // than the small strain: a large rotation strains it too, and a linear material misjudges both.
  std::vector<double> ElementStrains(const Vector& u) const;
  // Per element, its rest volume (2D: area x thickness), in element order.
  std::vector<double> ElementVolumes() const;
  // Total rest volume (2D: area x thickness).
  double Volume() const;
  // The smallest element quality (SimplexQuality, unsigned) and the element attaining it.
  std::pair<double, int> WorstQuality() const;

 private:
  int dimension_ = 2;
  int node_count_ = 0;
  Vector rest_;
  bool linear_ = true;
  std::vector<Element<2>> elements2_;
  std::vector<Element<3>> elements3_;
  std::vector<MaterialLaw<2>> laws2_;
  std::vector<MaterialLaw<3>> laws3_;
};

// Quality of a simplex from its nodes' positions (d + 1 columns): 1 for an equilateral one,
// 0 for a degenerate one; signed like its orientation.
double SimplexQuality(int dimension, const Matrix& corners);

}  // namespace springfit::fem
