// The genes as springs: each gene's node pair and unit rest direction, its force column on a
// support's free degrees of freedom and its elongation under a displacement
// (docs/ARCHITECTURE.md, "The probe fit").
//
// A spring e over nodes (i, j) with unit rest direction n_e has the force column
// g_e = (-n_e on i, +n_e on j); at a displacement u its elongation is delta_e = g_e^T u, and the
// rest stiffness of a model is K(k) = sum_e k_e g_e g_e^T. Every fit's sensitivities
// (spring_sensitivities.h), the held modes' slopes (mode_cuts.h) and the mode lift
// (mode_lift.h) are written in these.
#pragma once

#include <vector>

#include "engine/api/problem.h"
#include "engine/problem/support_system.h"

namespace springfit::response {

// Per gene, its spring's nodes and unit rest direction.
struct GeneSprings {
  int dimension = 2;
  std::vector<NodePair> pairs;
  Matrix directions;  // d x genes
  int size() const { return static_cast<int>(pairs.size()); }
};
GeneSprings GeneSpringsOf(const Problem& problem);

// g_e's entries on a support's free degrees of freedom: up to 2d (index, value) pairs.
struct SpringColumn {
  int count = 0;
  int index[6];
  double value[6];
  // g_e^T z for z on the support's free degrees of freedom.
  double Dot(const double* z) const {
    double v = 0.0;
    for (int a = 0; a < count; ++a) v += value[a] * z[index[a]];
    return v;
  }
  // y += s g_e.
  void AddTo(double s, double* y) const {
    for (int a = 0; a < count; ++a) y[index[a]] += s * value[a];
  }
};
std::vector<SpringColumn> FreeColumns(const GeneSprings& springs, const SupportSystem& support);

// delta_e = g_e^T u for every gene (u flat d*n).
Vector Elongations(const GeneSprings& springs, const Vector& u);

}  // namespace springfit::response
