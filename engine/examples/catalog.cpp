#include "engine/examples/catalog.h"

#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "engine/api/problem.h"
#include "engine/problem/small_strain.h"
#include "engine/runtime/number_text.h"
#include "engine/search/random_stream.h"

namespace springfit::examples {
namespace {

// A simplex whose signed measure keeps less than this fraction of its rest value is flattened.
constexpr double kFlattenedRatio = 1e-3;

int GridIndex(const std::vector<int>& n, int x, int y, int z) {
  return x + n[0] * (y + n[1] * z);
}

double SignedMeasure(int d, const Vector& x, const std::vector<int>& s) {
  if (d == 2) {
    const Eigen::Vector2d a = x.segment<2>(2 * s[1]) - x.segment<2>(2 * s[0]);
    const Eigen::Vector2d b = x.segment<2>(2 * s[2]) - x.segment<2>(2 * s[0]);
    return a.x() * b.y() - a.y() * b.x();
  }
  Eigen::Matrix3d m;
  for (int c = 0; c < 3; ++c) m.col(c) = x.segment<3>(3 * s[c + 1]) - x.segment<3>(3 * s[0]);
  return m.determinant();
}

}  // namespace

Scene PaperGrid(const std::string& name, bool anisotropic) {
  Scene s;
  s.name = name;
  const std::vector<int> n{5, 5};
  s.dimension = 2;
  s.rest = GridNodes(n, 1.0);
  s.candidates.kind = CandidateSpec::Kind::kGrid;
  s.reference.kind = Reference::Kind::kMss;
  s.reference.stiffness = {1.0};
  for (const NodePair& p : GridNeighbourSprings(n)) {
    // '\' diagonals join (x, y+1) with (x+1, y): their indices differ by n-1.
    const bool backslash = p.second - p.first == n[0] - 1;
    if (!(anisotropic && backslash)) s.reference.springs.push_back(p);
  }
  s.description = anisotropic
                      ? "5x5 grid, reference: horizontals, verticals and the '/' diagonal of every "
                        "cell (56 springs); paper7 loads of 0.05 k h (Bianchi et al. 2003)"
                      : "5x5 grid, reference: all 72 springs of the 8-neighbourhood; paper7 loads "
                        "of 0.05 k h (Bianchi et al. 2003)";
  s.load_cases = Paper7LoadCases(2, s.rest, 0.05);
  CheckFoldFree(s, GridSimplices(n));
  return s;
}

Scene Grid3d() {
  Scene s;
  s.name = "grid3d-4x4x4";
  s.description =
      "4x4x4 grid, 26-neighbourhood candidates, reference: every candidate; paper7 extended to "
      "3D (9 load cases) at 5% strain";
  const std::vector<int> n{4, 4, 4};
  s.dimension = 3;
  s.rest = GridNodes(n, 1.0);
  s.candidates.kind = CandidateSpec::Kind::kGrid;
  s.reference.springs = GridNeighbourSprings(n);
  s.reference.stiffness = {1.0};
  s.load_cases = Paper7LoadCases(3, s.rest, 1.0);
  ScaleLoadsToStrain(s, 0.05);
  CheckFoldFree(s, GridSimplices(n));
  return s;
}

Scene Stiff2d() {
  Scene s;
  s.name = "stiff-2d";
  s.description =
      "5x5 grid, reference: all 72 springs with stiffness spread log-uniformly over 1e-4..1e4; "
      "paper7 loads at 5% strain; training stiffness 1";
  const std::vector<int> n{5, 5};
  s.dimension = 2;
  s.rest = GridNodes(n, 1.0);
  s.candidates.kind = CandidateSpec::Kind::kGrid;
  s.reference.springs = GridNeighbourSprings(n);
  const int m = static_cast<int>(s.reference.springs.size());
  // Exponents j / (m-1) * 8 - 4 for j = 0..m-1, permuted by a stride coprime with m so that
  // neighbouring springs differ widely: both ends 1e-4 and 1e4 occur.
  for (int i = 0; i < m; ++i) {
    const int j = (i * 29) % m;
    s.reference.stiffness.push_back(std::pow(10.0, -4.0 + 8.0 * j / (m - 1)));
  }
  s.training_stiffness = 1.0;
  s.load_cases = Paper7LoadCases(2, s.rest, 1.0);
  ScaleLoadsToStrain(s, 0.05);
  CheckFoldFree(s, GridSimplices(n));
  return s;
}

Scene Kidney2d(const SimplexMesh& mesh) {
  Scene s;
  s.name = "kidney-2d";
  s.description =
      "irregular triangulated kidney cross-section (gmsh, 99 nodes), reference: the "
      "triangulation's edges, candidates: 8 nearest neighbours; paper7 loads on opposite ends "
      "at 5% strain";
  s.dimension = 2;
  s.rest = mesh.nodes;
  s.candidates.kind = CandidateSpec::Kind::kNearest;
  s.candidates.k = 8;
  const std::vector<std::vector<int>>& triangles = mesh.elements;
  std::vector<NodePair> edges;
  for (const auto& t : triangles) {
    for (int e = 0; e < 3; ++e) {
      const int a = t[e], b = t[(e + 1) % 3];
      edges.push_back({std::min(a, b), std::max(a, b)});
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  s.reference.springs = edges;
  s.reference.stiffness = {1.0};
  s.load_cases = Paper7LoadCases(2, s.rest, 1.0, 0.12);
  ScaleLoadsToStrain(s, 0.05);
  CheckFoldFree(s, triangles);
  return s;
}

namespace {

// SplitMix64: a fixed hash, so that which springs a ThinnedGrid keeps depends only on the
// seed and the pair, not on a library's random engine.
std::uint64_t Mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

double UnitHash(std::uint64_t seed, std::uint64_t a, std::uint64_t b) {
  return static_cast<double>(Mix(Mix(Mix(seed) ^ a) ^ b) >> 11) * (1.0 / 9007199254740992.0);
}

}  // namespace

Scene ThinnedGrid(const std::vector<int>& n, std::uint64_t seed, double stiffness_decades) {
  Scene s;
  const int d = static_cast<int>(n.size());
  s.dimension = d;
  s.name = "thinned-grid";
  for (std::size_t a = 0; a < n.size(); ++a) {
    s.name += a ? "x" : "-";  // two appends: GCC 12 warns falsely (-Wrestrict) on "x" + string
    s.name += std::to_string(n[a]);
  }
  s.description = "grid with a thinned, varied-stiffness reference (examples::ThinnedGrid, seed " +
                  std::to_string(seed) + ")";
  s.rest = GridNodes(n, 1.0);
  s.candidates.kind = CandidateSpec::Kind::kGrid;
  auto coords = [&](int node) {
    std::vector<int> c(d);
    for (int a = 0; a < d; ++a) {
      c[a] = node % n[a];
      node /= n[a];
    }
    return c;
  };
  auto index = [&](const std::vector<int>& c) {
    int node = 0;
    for (int a = d - 1; a >= 0; --a) node = node * n[a] + c[a];
    return node;
  };
  for (const NodePair& p : GridNeighbourSprings(n)) {
    const std::vector<int> ci = coords(p.first), cj = coords(p.second);
    int moved = 0;
    for (int a = 0; a < d; ++a) moved += ci[a] != cj[a];
    bool keep = true;
    if (moved == 2) {
      // A face diagonal: the face is named by its lowest corner and its two axes; one of its
      // two diagonals is always kept, the other with probability 1/2.
      std::vector<int> corner(d);
      for (int a = 0; a < d; ++a) corner[a] = std::min(ci[a], cj[a]);
      const int face = index(corner);
      std::uint64_t axes = 0;
      for (int a = 0; a < d; ++a) axes |= static_cast<std::uint64_t>(ci[a] != cj[a]) << a;
      const bool through_corner = index(ci) == face || index(cj) == face;
      const bool always = UnitHash(seed, static_cast<std::uint64_t>(face), axes) < 0.5;
      keep = through_corner == always || UnitHash(seed, static_cast<std::uint64_t>(p.first),
                                                  static_cast<std::uint64_t>(p.second)) < 0.5;
    } else if (moved == 3) {
      keep = UnitHash(seed, static_cast<std::uint64_t>(p.first),
                      static_cast<std::uint64_t>(p.second)) < 0.5;
    }
    if (!keep) continue;
    s.reference.springs.push_back(p);
    const double u = UnitHash(seed + 1, static_cast<std::uint64_t>(p.first),
                              static_cast<std::uint64_t>(p.second));
    s.reference.stiffness.push_back(std::pow(10.0, stiffness_decades * (u - 0.5)));
  }
  s.training_stiffness = 1.0;
  s.load_cases = Paper7LoadCases(d, s.rest, 1.0);
  ScaleLoadsToStrain(s, 0.05);
  return s;
}

Scene WithMeasurementNoise(const Scene& scene, double fraction, std::uint64_t seed) {
  const Problem problem = Problem::Build(scene);
  const int d = problem.dimension();
  const int n = scene.node_count();
  RandomStream random(seed);
  auto gaussian = [&random] {
    // Box-Muller; 1 - Uniform() is in (0, 1], so the logarithm is finite.
    const double radius = std::sqrt(-2.0 * std::log(1.0 - random.Uniform()));
    return radius * std::cos(2.0 * std::numbers::pi * random.Uniform());
  };
  Scene noisy = scene;
  noisy.name += "-noise" + NumberText(fraction, 6) + "-s" + std::to_string(seed);
  noisy.description = scene.description + "; reference positions with Gaussian noise of " +
                      std::to_string(fraction) + " x the RMS displacement (seed " +
                      std::to_string(seed) + ")";
  noisy.training_stiffness = problem.training_stiffness();
  noisy.reference = Reference{};
  noisy.reference.kind = Reference::Kind::kPositions;
  for (const PreparedLoadCase& lc : problem.load_cases()) {
    const FreeNodes& free = problem.free_sets()[lc.free_set];
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
      if (free.free_index[i] >= 0) sum += lc.reference.segment(d * i, d).squaredNorm();
    }
    const double sigma = fraction * std::sqrt(sum / std::max(free.count, 1));
    Vector positions = scene.rest + lc.reference;
    for (int i = 0; i < n; ++i) {
      if (free.free_index[i] < 0) continue;
      for (int a = 0; a < d; ++a) positions[d * i + a] += sigma * gaussian();
    }
    noisy.reference.positions.push_back(std::move(positions));
  }
  return noisy;
}

Vector GridNodes(const std::vector<int>& n, double spacing) {
  const int d = static_cast<int>(n.size());
  const int nz = d == 3 ? n[2] : 1;
  Vector rest(d * n[0] * n[1] * nz);
  int i = 0;
  for (int z = 0; z < nz; ++z) {
    for (int y = 0; y < n[1]; ++y) {
      for (int x = 0; x < n[0]; ++x) {
        rest[d * i] = spacing * x;
        rest[d * i + 1] = spacing * y;
        if (d == 3) rest[d * i + 2] = spacing * z;
        ++i;
      }
    }
  }
  return rest;
}

std::vector<NodePair> GridNeighbourSprings(const std::vector<int>& n) {
  const int d = static_cast<int>(n.size());
  const int nz = d == 3 ? n[2] : 1;
  std::vector<NodePair> springs;
  for (int z = 0; z < nz; ++z) {
    for (int y = 0; y < n[1]; ++y) {
      for (int x = 0; x < n[0]; ++x) {
        const int i = GridIndex(n, x, y, z);
        for (int dz = (d == 3 ? -1 : 0); dz <= (d == 3 ? 1 : 0); ++dz) {
          for (int dy = -1; dy <= 1; ++dy) {
            for (int dx = -1; dx <= 1; ++dx) {
              const int X = x + dx, Y = y + dy, Z = z + dz;
              if (X < 0 || Y < 0 || Z < 0 || X >= n[0] || Y >= n[1] || Z >= nz) continue;
              const int j = GridIndex(n, X, Y, Z);
              if (j > i) springs.push_back({i, j});
            }
          }
        }
      }
    }
  }
  std::sort(springs.begin(), springs.end());
  return springs;
}

const std::vector<Paper7Pattern>& Paper7Patterns(int d) {
  static const std::vector<Paper7Pattern> two = {
      {"stretch +y", 1, 1, 1}, {"compression -y", 1, 1, -1}, {"shear +x", 1, 0, 1},
      {"shear -x", 1, 0, -1},  {"stretch +x", 0, 0, 1},      {"shear +y", 0, 1, 1},
      {"shear -y", 0, 1, -1}};
  static const std::vector<Paper7Pattern> three = {
      {"stretch +z", 2, 2, 1},   {"compression -z", 2, 2, -1}, {"shear +x", 2, 0, 1},
      {"shear -x", 2, 0, -1},    {"shear +y", 2, 1, 1},        {"stretch +x", 0, 0, 1},
      {"shear +y (x)", 0, 1, 1}, {"shear -y (x)", 0, 1, -1},   {"shear +z (x)", 0, 2, 1}};
  return d == 2 ? two : three;
}

std::vector<int> SideNodes(int d, const Vector& rest, int axis, bool low, double band) {
  const int n = static_cast<int>(rest.size()) / d;
  const BoundingBox box = BoundingBox::Of(d, rest);
  const double width = std::max(band * (box.hi[axis] - box.lo[axis]), 1e-9 * box.Diagonal());
  std::vector<int> nodes;
  for (int i = 0; i < n; ++i) {
    const double x = rest[d * i + axis];
    if (low ? x <= box.lo[axis] + width : x >= box.hi[axis] - width) nodes.push_back(i);
  }
  return nodes;
}

std::vector<LoadCase> Paper7LoadCases(int d, const Vector& rest, double magnitude, double band) {
  std::vector<LoadCase> cases;
  for (const Paper7Pattern& p : Paper7Patterns(d)) {
    LoadCase lc;
    lc.name = p.name;
    lc.fixed = SideNodes(d, rest, p.fixed_axis, true, band);
    Vector load = Vector::Zero(d);  // not Unit() * sign: that writes -0.0 components
    load[p.load_axis] = p.sign * magnitude;
    lc.forces.push_back({SideNodes(d, rest, p.fixed_axis, false, band), load, false, {}});
    cases.push_back(std::move(lc));
  }
  return cases;
}

void ScaleLoadsToStrain(Scene& scene, double strain) {
  const int d = scene.dimension;
  const BoundingBox box = scene.Bounds();
  const double extent = (box.hi - box.lo).maxCoeff();
  // A load this small (relative to the reference's stiffness) is deep in the linear regime.
  constexpr double kProbe = 1e-6;
  Scene probe = scene;
  for (LoadCase& lc : probe.load_cases) {
    for (NodalLoad& f : lc.forces) f.value *= kProbe / f.value.norm();
    for (Traction& t : lc.tractions) t.value *= kProbe / t.value.norm();
  }
  // The probe is solved in the small-load limit, where every material is the linear one.
  const Problem problem = Problem::Build(probe);
  for (std::size_t k = 0; k < scene.load_cases.size(); ++k) {
    const double umax = LargestNodalDisplacement(d, problem.load_cases()[k].reference);
    std::vector<NodalLoad>& forces = scene.load_cases[k].forces;
    for (std::size_t m = 0; m < forces.size(); ++m) {
      forces[m].value = probe.load_cases[k].forces[m].value * (strain * extent / umax);
    }
    std::vector<Traction>& tractions = scene.load_cases[k].tractions;
    for (std::size_t m = 0; m < tractions.size(); ++m) {
      tractions[m].value = probe.load_cases[k].tractions[m].value * (strain * extent / umax);
    }
  }
}

void CheckFoldFree(const Scene& scene, const std::vector<std::vector<int>>& simplices) {
  const Problem problem = Problem::Build(scene);
  const int d = scene.dimension;
  for (std::size_t k = 0; k < problem.load_cases().size(); ++k) {
    const Vector deformed = scene.rest + problem.load_cases()[k].reference;
    for (const std::vector<int>& s : simplices) {
      const double before = SignedMeasure(d, scene.rest, s);
      const double after = SignedMeasure(d, deformed, s);
      if (!(after / before > kFlattenedRatio)) {
        throw std::logic_error("example '" + scene.name + "': load case " + std::to_string(k) +
                               " inverts or flattens a cell");
      }
    }
  }
}

std::vector<std::vector<int>> GridSimplices(const std::vector<int>& n) {
  const int d = static_cast<int>(n.size());
  std::vector<std::vector<int>> simplices;
  if (d == 2) {
    for (int y = 0; y + 1 < n[1]; ++y) {
      for (int x = 0; x + 1 < n[0]; ++x) {
        const int a = GridIndex(n, x, y, 0), b = GridIndex(n, x + 1, y, 0);
        const int c = GridIndex(n, x + 1, y + 1, 0), e = GridIndex(n, x, y + 1, 0);
        simplices.push_back({a, b, c});
        simplices.push_back({a, c, e});
        simplices.push_back({a, b, e});
        simplices.push_back({b, c, e});
      }
    }
    return simplices;
  }
  for (int z = 0; z + 1 < n[2]; ++z) {
    for (int y = 0; y + 1 < n[1]; ++y) {
      for (int x = 0; x + 1 < n[0]; ++x) {
        for (int corner = 0; corner < 8; ++corner) {
          const int cx = corner & 1, cy = (corner >> 1) & 1, cz = (corner >> 2) & 1;
          const int sx = cx ? -1 : 1, sy = cy ? -1 : 1, sz = cz ? -1 : 1;
          simplices.push_back({GridIndex(n, x + cx, y + cy, z + cz),
                               GridIndex(n, x + cx + sx, y + cy, z + cz),
                               GridIndex(n, x + cx, y + cy + sy, z + cz),
                               GridIndex(n, x + cx, y + cy, z + cz + sz)});
        }
      }
    }
  }
  return simplices;
}

}  // namespace springfit::examples
