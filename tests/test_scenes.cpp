#include "tests/test_scenes.h"

#include "engine/examples/catalog.h"

namespace springfit::testing {

Scene GridScene(int dimension, int n, double h, double k, double magnitude) {
  Scene s;
  s.name = "grid";
  s.dimension = dimension;
  std::vector<int> dims(dimension, n);
  s.rest = examples::GridNodes(dims, h);
  s.candidates.kind = CandidateSpec::Kind::kGrid;
  s.reference.springs = examples::GridNeighbourSprings(dims);
  s.reference.stiffness = {k};
  s.load_cases = examples::Paper7LoadCases(dimension, s.rest, magnitude * k * h);
  return s;
}

Scene JitteredScene(int dimension, int n, double jitter, std::uint32_t seed) {
  Scene s = GridScene(dimension, n);
  TestRandom random(seed);
  for (Eigen::Index i = 0; i < s.rest.size(); ++i)
    s.rest[i] += jitter * (2.0 * random.Uniform() - 1.0);
  // Keep the boundary rows/columns exactly on their planes so paper7 finds the same sides.
  const int d = dimension;
  for (int i = 0; i < s.node_count(); ++i) {
    for (int a = 0; a < d; ++a) {
      const double x = std::round(s.rest[d * i + a]);
      if (x == 0.0 || x == n - 1) s.rest[d * i + a] = x;
    }
  }
  s.candidates.kind = CandidateSpec::Kind::kNearest;
  s.candidates.k = dimension == 2 ? 8 : 18;
  s.load_cases = examples::Paper7LoadCases(dimension, s.rest, 0.05);
  return s;
}

Scene ScaledScene(const Scene& scene, double s) {
  Scene out = scene;
  out.rest *= s;
  for (double& h : out.candidates.spacing) h *= s;
  out.candidates.radius *= s;
  for (LoadCase& lc : out.load_cases) {
    for (NodalLoad& f : lc.forces) f.value *= s;
    for (NodalLoad& u : lc.displacements) u.value *= s;
  }
  for (Vector& p : out.reference.positions) p *= s;
  return out;
}

}  // namespace springfit::testing
