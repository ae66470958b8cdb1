#include "engine/fem/fem_validation.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

#include "engine/api/scene.h"
#include "engine/fem/fem_model.h"
#include "engine/runtime/input_error.h"
#include "engine/runtime/number_text.h"

namespace springfit::fem {
namespace {

// An element whose quality (1 = equilateral) is below this is degenerate: its stiffness
// would dominate the system's conditioning by more than the factorisation can bear.
constexpr double kDegenerateQuality = 1e-8;

std::string Index(const std::string& path, std::size_t i) {
  return path + "[" + std::to_string(i) + "]";
}

std::string Number(double v) {
  return NumberText(v, 6);
}

// How the user knows element `e`, as a prefix of its message (its index is in the path).
std::string ElementTagged(const Scene& s, std::size_t e) {
  const std::string tag = MeshElementTag(s, e);
  return tag.empty() ? "" : "(" + tag + ") ";
}

void CheckMaterial(const Material& m, const std::string& path) {
  if (!std::isfinite(m.young) || !(m.young > 0.0)) {
    throw InputError(path + ".young", "must be a finite number > 0, got " + Number(m.young));
  }
  // As every stiffness of a scene (scene_validation.cpp, kMaxMagnitude): beyond, energies
  // overflow or underflow double precision.
  if (m.young < 1e-100 || m.young > 1e100) {
    throw InputError(path + ".young", Number(m.young) +
                                          " is outside [1e-100, 1e+100]: rescale the scene's "
                                          "units (springfit computes in double precision)");
  }
  if (!std::isfinite(m.poisson) || !(m.poisson > -1.0 && m.poisson < 0.5)) {
    throw InputError(path + ".poisson",
                     "must be in (-1, 0.5), got " + Number(m.poisson) +
                         (m.poisson >= 0.5 && std::isfinite(m.poisson)
                              ? ": an incompressible material has no displacement-only FEM "
                                "model; for soft tissue use 0.49 (nearly incompressible)"
                              : ""));
  }
  if (m.density && (!std::isfinite(*m.density) || !(*m.density > 0.0) || *m.density > 1e100 ||
                    *m.density < 1e-100)) {
    throw InputError(path + ".density",
                     "must be a finite number in [1e-100, 1e+100], got " + Number(*m.density));
  }
}

// Which side of the facet's line (2D) or plane (3D) point p lies on: +1, -1, or 0.
double Side(int d, const Vector& rest, const std::vector<int>& facet, int p) {
  Matrix m(d, d);
  for (int a = 1; a < d; ++a)
    m.col(a - 1) = rest.segment(d * facet[a], d) - rest.segment(d * facet[0], d);
  m.col(d - 1) = rest.segment(d * p, d) - rest.segment(d * facet[0], d);
  const double det = m.determinant();
  return det > 0.0 ? 1.0 : det < 0.0 ? -1.0 : 0.0;
}

// Element orientation is free (either node order), so an element inverted at rest shows as
// a fold: two elements sharing an edge (face) lie on the same side of it. More than two
// elements on one edge (face) is not a manifold mesh either.
void CheckNoFold(const Scene& s) {
  const FemReference& fem = s.reference.fem;
  const int d = s.dimension;
  std::map<std::vector<int>, std::pair<int, int>> owner;  // facet -> (element, opposite node)
  ForEachFacet(fem, d, [&](std::size_t e, const std::vector<int>& facet, int opposite) {
    const auto [it, inserted] = owner.emplace(facet, std::make_pair(static_cast<int>(e), opposite));
    if (inserted) return;
    const int other = it->second.first;
    const std::string nodes = NodesNamed(s, facet);
    if (other < 0) {
      throw InputError(Index("reference.elements", e), ElementTagged(s, e) +
                                                           "a third element on the " +
                                                           (d == 2 ? "edge" : "face") + " (" +
                                                           nodes + "): the mesh is not a manifold");
    }
    if (Side(d, s.rest, facet, opposite) == Side(d, s.rest, facet, it->second.second)) {
      throw InputError(Index("reference.elements", e),
                       ElementTagged(s, e) + "inverted at rest: it overlaps reference.elements[" +
                           std::to_string(other) + "] " + ElementTagged(s, other) +
                           "across their " + (d == 2 ? "edge" : "face") + " (" + nodes +
                           ") (the mesh folds over itself there)");
    }
    it->second.first = -1;  // two elements seen
  });
}

}  // namespace

void ValidateFemReference(const Scene& s) {
  const FemReference& fem = s.reference.fem;
  const int d = s.dimension;
  const int n = s.node_count();
  if (fem.elements.empty()) throw InputError("reference.elements", "must not be empty");
  std::vector<bool> used(n, false);
  for (std::size_t e = 0; e < fem.elements.size(); ++e) {
    const std::string p = Index("reference.elements", e);
    const std::vector<int>& el = fem.elements[e];
    if (static_cast<int>(el.size()) != d + 1) {
      throw InputError(p, ElementTagged(s, e) + "a " +
                              (d == 2 ? "2D element is a 3-node triangle"
                                      : "3D element is a 4-node tetrahedron") +
                              ", got " + std::to_string(el.size()) + " nodes");
    }
    Matrix corners(d, d + 1);
    for (int a = 0; a <= d; ++a) {
      if (el[a] < 0 || el[a] >= n) {
        throw InputError(Index(p, a), "node index " + std::to_string(el[a]) + " out of range [0, " +
                                          std::to_string(n) + ")");
      }
      for (int b = 0; b < a; ++b) {
        if (el[a] == el[b])
          throw InputError(Index(p, a),
                           ElementTagged(s, e) + NodesNamed(s, {el[a]}) + " is listed twice");
      }
      used[el[a]] = true;
      corners.col(a) = s.rest.segment(d * el[a], d);
    }
    const double q = SimplexQuality(d, corners);
    if (!(std::abs(q) >= kDegenerateQuality)) {
      throw InputError(p, ElementTagged(s, e) + "degenerate element (quality " +
                              Number(std::abs(q)) + ", 1 = equilateral): its " + NodesNamed(s, el) +
                              " are " + (d == 2 ? "on one line" : "in one plane"));
    }
  }
  CheckNoFold(s);
  for (int i = 0; i < n; ++i) {
    if (!used[i]) {
      throw InputError(
          "reference.elements",
          NodesNamed(s, {i}) + " belongs to no element (every node of an FEM reference must)");
    }
  }
  if (fem.materials.empty()) throw InputError("reference.material", "required");
  if (fem.regions) {
    for (std::size_t m = 0; m < fem.materials.size(); ++m)
      CheckMaterial(fem.materials[m], Index("reference.materials", m));
    if (fem.element_material.size() != fem.elements.size()) {
      throw InputError("reference.element_materials",
                       "expected one material index per element (" +
                           std::to_string(fem.elements.size()) + "), got " +
                           std::to_string(fem.element_material.size()));
    }
    for (std::size_t e = 0; e < fem.element_material.size(); ++e) {
      const int m = fem.element_material[e];
      if (m < 0 || m >= static_cast<int>(fem.materials.size())) {
        throw InputError(Index("reference.element_materials", e),
                         "material index " + std::to_string(m) + " out of range [0, " +
                             std::to_string(fem.materials.size()) + ")");
      }
    }
  } else {
    CheckMaterial(fem.materials[0], "reference.material");
  }
  if (d == 3 && fem.plane_given) throw InputError("reference.plane", "only applies to 2D scenes");
  if (d == 3 && fem.thickness_given)
    throw InputError("reference.thickness", "only applies to 2D scenes");
  if (!std::isfinite(fem.thickness) || !(fem.thickness > 0.0)) {
    throw InputError("reference.thickness",
                     "must be a finite number > 0, got " + Number(fem.thickness));
  }
}

}  // namespace springfit::fem
