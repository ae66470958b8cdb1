// The FEM reference's equilibria: the patch test, closed-form bars (linear, St. Venant-
// Kirchhoff, neo-Hookean; 2D and 3D), the tangent against finite differences, tractions,
// and the reference's failures (no equilibrium, free modes, validation).
#include "engine/fem/fem_equilibrium.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "engine/api/problem.h"
#include "engine/examples/simplex_mesh.h"
#include "engine/fem/traction.h"
#include "engine/runtime/input_error.h"
#include "tests/test_scenes.h"

namespace springfit {
namespace {

using examples::SimplexMesh;

// Agreement with closed forms: the solver converges to 1e-10 of the force scale, so
// displacements agree to about that relative to their size.
constexpr double kClosedFormTolerance = 1e-9;

Scene FemScene(const SimplexMesh& mesh, int d, Material material,
               PlaneMode plane = PlaneMode::kStress, double thickness = 1.0) {
  Scene s;
  s.name = "fem-test";
  s.dimension = d;
  s.rest = mesh.nodes;
  s.candidates.kind = CandidateSpec::Kind::kNearest;
  s.candidates.k = 6;
  s.reference.kind = Reference::Kind::kFem;
  s.reference.fem.elements = mesh.elements;
  s.reference.fem.materials = {material};
  s.reference.fem.plane = plane;
  s.reference.fem.thickness = thickness;
  return s;
}

// Nodes whose coordinate along `axis` is within 1e-9 of `value`.
std::vector<int> NodesAt(const Scene& s, int axis, double value) {
  std::vector<int> out;
  for (int i = 0; i < s.node_count(); ++i) {
    if (std::abs(s.rest[s.dimension * i + axis] - value) < 1e-9) out.push_back(i);
  }
  return out;
}

// A bar along x: left end fixed, a total traction `total_x` on the right end.
Scene Bar(int d, MaterialModel model, double total_x, double poisson = 0.0) {
  const double h = 0.25;
  const SimplexMesh mesh = d == 2 ? examples::TriangulatedRectangle(8, 2, h, true)
                                  : examples::TetrahedralBlock(8, 2, 2, h);
  Scene s = FemScene(mesh, d, Material{model, 3.0, poisson}, PlaneMode::kStrain, 0.2);
  s.node_sets["left"] = NodesAt(s, 0, 0.0);
  s.node_sets["right"] = NodesAt(s, 0, 8 * h);
  LoadCase lc;
  lc.name = "pull";
  lc.fixed = s.node_sets["left"];
  lc.fixed_set = "left";
  Traction t;
  t.on = "right";
  t.nodes = s.node_sets["right"];
  t.value = Vector::Zero(d);
  t.value[0] = total_x;
  lc.tractions.push_back(t);
  s.load_cases.push_back(lc);
  return s;
}

// The bar's cross-section area (2D: width x thickness).
double BarSection(int d) {
  return d == 2 ? 0.5 * 0.2 : 0.5 * 0.5;
}

// Solves for the stretch lambda with nominal stress p: Newton on a monotone law.
template <typename Law>
double Stretch(double p, Law nominal_stress) {
  double l = 1.0;
  for (int it = 0; it < 100; ++it) {
    const double f = nominal_stress(l) - p;
    const double df = (nominal_stress(l + 1e-7) - nominal_stress(l - 1e-7)) / 2e-7;
    l -= f / df;
  }
  return l;
}

void ExpectUniformStretch(const Problem& p, double lambda) {
  const Scene& s = p.scene();
  const int d = s.dimension;
  const Vector& u = p.load_cases()[0].reference;
  const double umax = (lambda - 1.0) * 2.0;
  for (int i = 0; i < s.node_count(); ++i) {
    EXPECT_NEAR(u[d * i], (lambda - 1.0) * s.rest[d * i], kClosedFormTolerance * std::abs(umax))
        << "node " << i;
    for (int a = 1; a < d; ++a)
      EXPECT_NEAR(u[d * i + a], 0.0, kClosedFormTolerance * std::abs(umax)) << "node " << i;
  }
}

TEST(FemEquilibrium, LinearBarMatchesClosedForm) {
  for (int d : {2, 3}) {
    const double total = 0.01;
    const Problem p = Problem::Build(Bar(d, MaterialModel::kLinear, total));
    // Poisson 0: uniaxial stress, eps = T / (E A) everywhere.
    ExpectUniformStretch(p, 1.0 + total / (3.0 * BarSection(d)));
    EXPECT_EQ(p.load_cases()[0].reference_solve->load_steps, 1);
  }
}

TEST(FemEquilibrium, StVenantKirchhoffBarMatchesClosedForm) {
  for (int d : {2, 3}) {
    const double total = 0.05 * 3.0 * BarSection(d);  // nominal stress 5% of E
    const Problem p = Problem::Build(Bar(d, MaterialModel::kStVenantKirchhoff, total));
    // Poisson 0: S = E E_xx, P = F S = E l (l^2 - 1) / 2.
    ExpectUniformStretch(
        p, Stretch(0.05 * 3.0, [](double l) { return 3.0 * l * (l * l - 1.0) / 2.0; }));
  }
}

TEST(FemEquilibrium, NeoHookeanBarMatchesClosedFormAtLargeStretch) {
  for (int d : {2, 3}) {
    // Poisson 0 (lambda = 0): P = mu (l - 1/l) along the bar, no lateral stress at stretch 1.
    const double mu = 3.0 / 2.0;
    const double p_nominal = 1.2 * mu;  // stretch about 1.8
    const Problem p = Problem::Build(Bar(d, MaterialModel::kNeoHookean, p_nominal * BarSection(d)));
    ExpectUniformStretch(p, Stretch(p_nominal, [&](double l) { return mu * (l - 1.0 / l); }));
  }
}

// Every node on the boundary of the mesh moved by the affine field u = A x + c, the interior
// free: the interior must follow the same field exactly (a constant F is an equilibrium of
// any hyperelastic law), on a mesh with jittered interior nodes.
void PatchTest(int d, MaterialModel model) {
  SimplexMesh mesh = d == 2 ? examples::TriangulatedRectangle(4, 4, 1.0, true)
                            : examples::TetrahedralBlock(3, 3, 3, 1.0);
  testing::TestRandom random(7);
  const int n = static_cast<int>(mesh.nodes.size()) / d;
  const double top = d == 2 ? 4.0 : 3.0;
  std::vector<bool> boundary(n, false);
  for (int i = 0; i < n; ++i) {
    for (int a = 0; a < d; ++a) {
      const double x = mesh.nodes[d * i + a];
      if (x < 1e-9 || x > top - 1e-9) boundary[i] = true;
    }
    if (!boundary[i]) {
      for (int a = 0; a < d; ++a) mesh.nodes[d * i + a] += 0.2 * (random.Uniform() - 0.5);
    }
  }
  Scene s = FemScene(mesh, d, Material{model, 2.0, 0.3});
  Matrix A = Matrix::Zero(d, d);
  for (int r = 0; r < d; ++r) {
    for (int c = 0; c < d; ++c) A(r, c) = 0.04 * (random.Uniform() - 0.5);
  }
  LoadCase lc;
  for (int i = 0; i < n; ++i) {
    if (!boundary[i]) continue;
    NodalLoad move;
    move.nodes = {i};
    move.value = A * s.rest.segment(d * i, d);
    lc.displacements.push_back(move);
  }
  s.load_cases.push_back(lc);
  const Problem p = Problem::Build(s);
  const Vector& u = p.load_cases()[0].reference;
  for (int i = 0; i < n; ++i) {
    const Vector expected = A * s.rest.segment(d * i, d);
    // The solver stops at 1e-10 of the force scale; the displacements then agree to about
    // 1e-10 times the system's condition number (small here).
    EXPECT_LT((u.segment(d * i, d) - expected).norm(), 1e-8 * top * A.norm()) << "node " << i;
  }
}

TEST(FemEquilibrium, PatchTestReproducesConstantStrain) {
  for (MaterialModel model :
       {MaterialModel::kLinear, MaterialModel::kStVenantKirchhoff, MaterialModel::kNeoHookean}) {
    PatchTest(2, model);
    PatchTest(3, model);
  }
}

TEST(FemEquilibrium, GradientAndTangentMatchFiniteDifferences) {
  for (int d : {2, 3}) {
    for (MaterialModel model :
         {MaterialModel::kLinear, MaterialModel::kStVenantKirchhoff, MaterialModel::kNeoHookean}) {
      const SimplexMesh mesh = d == 2 ? examples::TriangulatedRectangle(3, 2, 1.0, false)
                                      : examples::TetrahedralBlock(2, 1, 1, 1.0);
      const Scene s = FemScene(mesh, d, Material{model, 1.5, 0.25}, PlaneMode::kStress, 0.3);
      const fem::FemModel model_ = fem::FemModel::Build(s);
      std::vector<bool> constrained(s.node_count(), false);
      constrained[0] = true;
      fem::FemEquilibriumSolver solver(model_, FreeNodes::FromConstrained(constrained));
      testing::TestRandom random(3);
      Vector u(s.rest.size()), f(s.rest.size());
      for (Eigen::Index i = 0; i < u.size(); ++i) {
        u[i] = 0.1 * (random.Uniform() - 0.5);
        f[i] = random.Uniform() - 0.5;
      }
      u.head(d).setZero();
      Vector g;
      solver.EnergyAndGradient(f, u, &g, true);
      const Matrix k = solver.AssembledHessian();
      const double step = 1e-6;
      for (int i = 1; i < s.node_count(); ++i) {
        for (int a = 0; a < d; ++a) {
          Vector plus = u, minus = u;
          plus[d * i + a] += step;
          minus[d * i + a] -= step;
          const double fd = (solver.EnergyAndGradient(f, plus, nullptr, false) -
                             solver.EnergyAndGradient(f, minus, nullptr, false)) /
                            (2 * step);
          const int row = d * (i - 1) + a;
          EXPECT_NEAR(fd, g[row], 1e-6 * (1.0 + g.cwiseAbs().maxCoeff()));
          Vector gp, gm;
          solver.EnergyAndGradient(f, plus, &gp, false);
          solver.EnergyAndGradient(f, minus, &gm, false);
          const Vector column = (gp - gm) / (2 * step);
          EXPECT_LT((column - k.col(row)).cwiseAbs().maxCoeff(), 1e-6 * k.cwiseAbs().maxCoeff());
        }
      }
    }
  }
}

TEST(FemEquilibrium, TractionsSpreadTheTotalForceConsistently) {
  // A traction's nodal forces add up to its total, and on a uniform edge the end nodes take
  // half the share of the inner ones.
  Scene s = Bar(2, MaterialModel::kLinear, 0.3);
  Vector force = Vector::Zero(s.rest.size());
  fem::AddTractionForces(s, s.load_cases[0].tractions[0], "load_cases[0].tractions[0]", force);
  double sum = 0.0;
  for (int i = 0; i < s.node_count(); ++i) sum += force[2 * i];
  EXPECT_NEAR(sum, 0.3, 1e-15);
  const std::vector<int>& right = s.node_sets["right"];  // y = 0, 0.25, 0.5
  EXPECT_NEAR(force[2 * right[0]], 0.075, 1e-15);
  EXPECT_NEAR(force[2 * right[1]], 0.15, 1e-15);
  EXPECT_NEAR(force[2 * right[2]], 0.075, 1e-15);
  // A set without a boundary edge is refused, naming the traction.
  Scene inner = s;
  inner.load_cases[0].tractions[0].nodes = {10};
  try {
    fem::AddTractionForces(inner, inner.load_cases[0].tractions[0], "load_cases[0].tractions[0]",
                           force);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "load_cases[0].tractions[0].on");
  }
}

TEST(FemEquilibrium, LengthScaleInvariance) {
  // Lengths x s, forces x s^2 (stress unchanged): displacements x s.
  const Problem a = Problem::Build(Bar(3, MaterialModel::kNeoHookean, 0.2));
  for (double scale : {1e-6, 1e6}) {
    Scene s = Bar(3, MaterialModel::kNeoHookean, 0.2 * scale * scale);
    s.rest *= scale;
    const Problem b = Problem::Build(s);
    const Vector& ua = a.load_cases()[0].reference;
    const Vector& ub = b.load_cases()[0].reference;
    EXPECT_LT((ub / scale - ua).cwiseAbs().maxCoeff(), 1e-9 * ua.cwiseAbs().maxCoeff()) << scale;
  }
}

TEST(FemEquilibrium, CompressionBeyondTheLimitLoadHasNoEquilibrium) {
  // St. Venant-Kirchhoff in uniaxial compression carries at most E / (3 sqrt 3) (nominal): at
  // 0.25 E the reference has no equilibrium, and preparing it says so with the load case.
  Scene s = Bar(2, MaterialModel::kStVenantKirchhoff, -0.25 * 3.0 * BarSection(2));
  try {
    Problem::Build(s);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "reference");
    EXPECT_NE(std::string(e.what()).find("load_cases[0]"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("load"), std::string::npos) << e.what();
  }
  // Below the bar's buckling load (Euler, clamped-free: about 0.013 E here) it converges.
  EXPECT_NO_THROW(
      Problem::Build(Bar(2, MaterialModel::kStVenantKirchhoff, -0.005 * 3.0 * BarSection(2))));
}

TEST(FemEquilibrium, AnIslandNotHeldByTheSupportsIsRefused) {
  // Two triangles that share no node: the second has no constrained node.
  SimplexMesh mesh;
  mesh.nodes.resize(12);
  mesh.nodes << 0, 0, 1, 0, 0, 1, 3, 0, 4, 0, 3, 1;
  mesh.elements = {{0, 1, 2}, {3, 4, 5}};
  Scene s = FemScene(mesh, 2, Material{MaterialModel::kLinear, 1.0, 0.3});
  LoadCase lc;
  lc.fixed = {0, 1};
  lc.forces.push_back({{2}, Vector::Unit(2, 1) * 0.01, true, {}});
  s.load_cases.push_back(lc);
  try {
    Problem::Build(s);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("free modes"), std::string::npos) << e.what();
  }
}

// A material past poisson 0.49 is taken (the tissue may be that), with a notice that linear
// elements lock under it, naming the field the user wrote; at 0.49 and below, none.
TEST(FemEquilibrium, ANearlyIncompressibleMaterialGetsANoticeOnLocking) {
  Scene s = Bar(2, MaterialModel::kLinear, 0.01);
  s.reference.fem.materials[0].poisson = 0.499;
  const std::vector<std::string> notices = SceneNotices(Problem::Build(s));
  ASSERT_EQ(notices.size(), 1u);
  EXPECT_NE(notices[0].find("reference.material.poisson: Poisson's ratio 0.499 is above 0.49: "
                            "linear triangles lock there (the volume is 500 times"),
            std::string::npos)
      << notices[0];
  s.reference.fem.materials[0].poisson = 0.49;
  EXPECT_TRUE(SceneNotices(Problem::Build(s)).empty());
}

TEST(FemEquilibrium, ValidationNamesTheField) {
  auto expect_path = [](Scene s, const std::string& path, const std::string& words) {
    try {
      Problem::Build(std::move(s));
      FAIL() << "expected an InputError at " << path;
    } catch (const InputError& e) {
      EXPECT_EQ(e.path(), path) << e.what();
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  const Scene bar = Bar(2, MaterialModel::kLinear, 0.01);
  Scene s = bar;
  s.reference.fem.materials[0].poisson = 0.5;
  expect_path(s, "reference.material.poisson", "(-1, 0.5)");
  s = bar;
  s.reference.fem.materials[0].young = -1.0;
  expect_path(s, "reference.material.young", "> 0");
  s = bar;
  s.reference.fem.elements[3].push_back(0);
  expect_path(s, "reference.elements[3]", "3-node triangle");
  s = bar;
  // Either node order is accepted...
  std::swap(s.reference.fem.elements[5][1], s.reference.fem.elements[5][2]);
  EXPECT_NO_THROW(Problem::Build(s));
  // ...but an element folded over its neighbour is inverted: D lies on A's side of B-C.
  {
    SimplexMesh fold;
    fold.nodes.resize(8);
    fold.nodes << 0, 0, 1, 0, 0, 1, 0.3, 0.3;  // A, B, C, D
    fold.elements = {{0, 1, 2}, {1, 2, 3}};
    s = FemScene(fold, 2, Material{MaterialModel::kLinear, 1.0, 0.3});
    LoadCase lc;
    lc.fixed = {0, 1};
    lc.forces.push_back({{2}, Vector::Unit(2, 1) * 0.01, true, {}});
    s.load_cases.push_back(lc);
  }
  expect_path(s, "reference.elements[1]", "inverted at rest");
  // An imported mesh's nodes are named by its own tags (Gmsh's node tags), which the user
  // knows, not by springfit's 0-based indices: the shared edge B-C is tags 102, 103.
  s.node_tags = {101, 102, 103, 104};
  expect_path(s, "reference.elements[1]", "edge (nodes 102, 103 (the mesh's tags))");
  // And the elements by theirs (Gmsh's element tags, a deck's element ids).
  s.reference.fem.element_tags = {3001, 3007};
  expect_path(s, "reference.elements[1]",
              "(the mesh's element 3007) inverted at rest: it overlaps reference.elements[0] (the "
              "mesh's element 3001) across");
  s = bar;
  s.reference.fem.elements[2][2] = 99;
  expect_path(s, "reference.elements[2][2]", "out of range");
  s = bar;
  {
    // Every element of the last node removed.
    const int last = s.node_count() - 1;
    auto& els = s.reference.fem.elements;
    els.erase(std::remove_if(els.begin(), els.end(),
                             [&](const std::vector<int>& e) {
                               return std::find(e.begin(), e.end(), last) != e.end();
                             }),
              els.end());
  }
  expect_path(s, "reference.elements", "belongs to no element");
  s.node_tags.resize(s.node_count());
  for (int i = 0; i < s.node_count(); ++i) s.node_tags[i] = 7001 + 2 * i;
  expect_path(
      s, "reference.elements",
      "node " + std::to_string(7001 + 2 * (s.node_count() - 1)) + " (the mesh's tags) belongs");
  s = bar;
  s.reference.fem.regions = true;
  s.reference.fem.materials.push_back(s.reference.fem.materials[0]);
  s.reference.fem.element_material.assign(s.reference.fem.elements.size(), 0);
  s.reference.fem.element_material[4] = 2;
  expect_path(s, "reference.element_materials[4]", "out of range");
  s = bar;
  s.reference.kind = Reference::Kind::kPositions;
  expect_path(s, "load_cases[0].tractions[0]", "needs a mesh");
}

TEST(FemEquilibrium, RegionsGiveEachElementItsMaterial) {
  // A bar of two materials in series (left half E, right half 3E), Poisson 0: the right end
  // moves T L/2 / (E A) + T L/2 / (3 E A).
  Scene s = Bar(2, MaterialModel::kLinear, 0.01);
  s.reference.fem.regions = true;
  s.reference.fem.materials = {Material{MaterialModel::kLinear, 3.0, 0.0},
                               Material{MaterialModel::kLinear, 9.0, 0.0}};
  for (const auto& e : s.reference.fem.elements) {
    double cx = 0.0;
    for (int node : e) cx += s.rest[2 * node] / 3.0;
    s.reference.fem.element_material.push_back(cx > 1.0 ? 1 : 0);
  }
  const Problem p = Problem::Build(s);
  const double expected = 0.01 * 1.0 / (3.0 * BarSection(2)) + 0.01 * 1.0 / (9.0 * BarSection(2));
  const int right = s.node_sets["right"][1];
  EXPECT_NEAR(p.load_cases()[0].reference[2 * right], expected, kClosedFormTolerance * expected);
}

}  // namespace
}  // namespace springfit
