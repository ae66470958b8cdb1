// The equilibrium solver: analytic answers, derivatives, force balance, backends.
#include "engine/model/equilibrium.h"

#include <cmath>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "engine/api/problem.h"
#include "tests/test_scenes.h"

namespace springfit {
namespace {

// Force balance is judged relative to the load: a converged solve leaves at most this
// fraction of the largest external force unbalanced at any free node.
constexpr double kForceBalance = 1e-9;

ActiveSprings AllSprings(const SpringGeometry& g, double k) {
  ActiveSprings a;
  for (int s = 0; s < g.size(); ++s) {
    a.index.push_back(s);
    a.stiffness.push_back(k);
  }
  return a;
}

std::vector<bool> Constrained(int n, std::initializer_list<int> nodes) {
  std::vector<bool> c(n, false);
  for (int i : nodes) c[i] = true;
  return c;
}

// A free node at the origin held by four springs of length 1 to fixed nodes on the axes,
// pushed along x to displacement delta: the x springs (stiffness k) give 2 k delta, the y
// springs (stiffness kv) 2 kv (L - 1) delta / L with L = sqrt(1 + delta^2). Solve for the
// force, then check the solver finds delta back. At delta = 0.9 one x spring is stretched to
// 1.9 times its length and the other compressed to a tenth of it; stiff y springs keep that
// state stable (with kv = k it would snap sideways).
TEST(Equilibrium, CrossMatchesAnalyticLargeDisplacement) {
  for (double delta : {1e-6, 0.1, 0.5, 0.9}) {
    Vector rest(10);
    rest << 0, 0, -1, 0, 1, 0, 0, -1, 0, 1;
    const SpringGeometry g(2, rest, {{0, 1}, {0, 2}, {0, 3}, {0, 4}});
    const double k = 3.0;
    const double kv = delta > 0.5 ? 20 * k : k;
    const double L = std::sqrt(1 + delta * delta);
    const double F = 2 * k * delta + 2 * kv * (L - 1) * delta / L;
    EquilibriumSolver solver(g, FreeNodes::FromConstrained(Constrained(5, {1, 2, 3, 4})));
    const ActiveSprings springs{{0, 1, 2, 3}, {k, k, kv, kv}};
    EXPECT_EQ(solver.RestMechanismModes(springs), 0);
    Vector force = Vector::Zero(10);
    force[0] = F;
    Vector u = Vector::Zero(10);
    const EquilibriumSummary summary = solver.Solve(springs, force, Vector::Zero(10), u);
    ASSERT_TRUE(summary.converged());
    EXPECT_NEAR(u[0], delta, 1e-12 * std::max(delta, 1e-3)) << delta;
    EXPECT_NEAR(u[1], 0.0, 1e-14);
    EXPECT_LE(summary.iterations, 8);
  }
}

// A straight chain of n springs, fixed at one end, the other end displaced along the chain:
// every spring takes the same stretch, up to 3x its length. At rest each interior node has no
// transverse stiffness: the rest check reports one mode per interior node, while under tension
// the exact Hessian is definite. (Under compression a free chain buckles into a zig-zag of
// unstressed springs, the true minimum; compression is tested on the cross above.)
TEST(Equilibrium, ChainUniformStretchUpToThreeTimesLength) {
  const int n = 6;
  Vector rest = Vector::Zero(2 * (n + 1));
  std::vector<NodePair> pairs;
  for (int i = 0; i <= n; ++i) rest[2 * i] = 0.5 * i;
  for (int i = 0; i < n; ++i) pairs.push_back({i, i + 1});
  const SpringGeometry g(2, rest, pairs);
  EquilibriumSolver solver(g, FreeNodes::FromConstrained(Constrained(n + 1, {0, n})));
  const ActiveSprings springs = AllSprings(g, 2.0);
  EXPECT_EQ(solver.RestMechanismModes(springs), n - 1);
  for (double stretch : {3.0, 1.5, 1.0001}) {
    Vector prescribed = Vector::Zero(2 * (n + 1));
    prescribed[2 * n] = (stretch - 1.0) * 0.5 * n;
    Vector u = Vector::Zero(2 * (n + 1));
    const EquilibriumSummary summary =
        solver.Solve(springs, Vector::Zero(2 * (n + 1)), prescribed, u);
    ASSERT_TRUE(summary.converged()) << stretch;
    for (int i = 0; i <= n; ++i) {
      EXPECT_NEAR(u[2 * i], (stretch - 1.0) * 0.5 * i, 1e-12)
          << "stretch " << stretch << " node " << i;
      EXPECT_EQ(u[2 * i + 1], 0.0);
    }
  }
}

TEST(Equilibrium, GradientAndHessianMatchFiniteDifferences) {
  for (int dim : {2, 3}) {
    const Scene scene = testing::JitteredScene(dim, 3, 0.2, 7);
    const Problem p = Problem::Build(scene);
    const SpringGeometry& g = p.candidates();
    testing::TestRandom random(11);
    ActiveSprings springs;
    for (int s = 0; s < g.size(); ++s) {
      springs.index.push_back(s);
      springs.stiffness.push_back(0.5 + random.Uniform());
    }
    const PreparedLoadCase& lc = p.load_cases()[0];
    EquilibriumSolver solver(g, p.free_sets()[lc.free_set]);
    const FreeNodes& free = solver.free_nodes();
    // A displacement large enough that some springs are compressed and some stretched.
    Vector u = Vector::Zero(lc.force.size());
    for (int i = 0; i < scene.node_count(); ++i) {
      if (free.free_index[i] >= 0) {
        for (int a = 0; a < dim; ++a) u[dim * i + a] = 0.3 * (2 * random.Uniform() - 1);
      }
    }
    for (bool projected : {false, true}) {
      Vector grad;
      solver.EnergyAndGradient(springs, lc.force, u, &grad, true, projected);
      const Matrix hessian = solver.AssembledHessian();
      const double h = 1e-6;
      for (int i = 0; i < scene.node_count(); ++i) {
        const int f = free.free_index[i];
        if (f < 0) continue;
        for (int a = 0; a < dim; ++a) {
          Vector up = u, um = u;
          up[dim * i + a] += h;
          um[dim * i + a] -= h;
          const double ep = solver.EnergyAndGradient(springs, lc.force, up, nullptr, false, false);
          const double em = solver.EnergyAndGradient(springs, lc.force, um, nullptr, false, false);
          EXPECT_NEAR(grad[dim * f + a], (ep - em) / (2 * h), 1e-7) << "dim " << dim;
          if (projected) continue;  // the projected Hessian is not a derivative
          Vector gp, gm;
          solver.EnergyAndGradient(springs, lc.force, up, &gp, false, false);
          solver.EnergyAndGradient(springs, lc.force, um, &gm, false, false);
          const Vector column = (gp - gm) / (2 * h);
          for (Eigen::Index r = 0; r < column.size(); ++r) {
            EXPECT_NEAR(hessian(r, dim * f + a), column[r], 1e-6) << "dim " << dim << " row " << r;
          }
        }
      }
      if (projected) {
        // Projected = exact minus a PSD correction: it must be PSD itself.
        Eigen::SelfAdjointEigenSolver<Matrix> eig(hessian);
        EXPECT_GE(eig.eigenvalues().minCoeff(), -1e-12);
      }
    }
  }
}

TEST(Equilibrium, ASoftRegionIsSolvedToItsOwnRoundOffNotTheStiffestSprings) {
  // Node 0 on two soft springs (k = 1) to fixed nodes 1 and 2, loaded by 1e-6; node 3 on two
  // springs of 1e8 to fixed nodes 4 and 5, unloaded. A floor set by the stiffest spring
  // (1e-13 x 1e8 x 1 = 1e-5) would call node 0 balanced before it moves.
  Vector rest(12);
  rest << 0, 0, -1, 0, 0, -1, 10, 0, 9, 0, 10, -1;
  const SpringGeometry g(2, rest, {{0, 1}, {0, 2}, {3, 4}, {3, 5}});
  EquilibriumSolver solver(g, FreeNodes::FromConstrained(Constrained(6, {1, 2, 4, 5})));
  const ActiveSprings springs{{0, 1, 2, 3}, {1.0, 1.0, 1e8, 1e8}};
  Vector force = Vector::Zero(12);
  force[0] = 1e-6;
  Vector u = Vector::Zero(12);
  const EquilibriumSummary summary = solver.Solve(springs, force, Vector::Zero(12), u);
  ASSERT_TRUE(summary.converged());
  EXPECT_GE(summary.iterations, 1);
  EXPECT_NEAR(u[0], 1e-6, 1e-12);  // the spring along x carries it all (to first order)
}

TEST(Equilibrium, SmallLoadLimitIsTheLinearSolve) {
  for (int dim : {2, 3}) {
    const Problem p = Problem::Build(testing::GridScene(dim, 4));
    const ActiveSprings springs = p.SpringsFromMask(*p.reference_mask());
    for (const PreparedLoadCase& lc : p.load_cases()) {
      EquilibriumSolver solver(p.candidates(), p.free_sets()[lc.free_set]);
      const FreeNodes& free = solver.free_nodes();
      const double scale = 1e-7;
      const Vector force = scale * lc.force;
      // K0 u = f on the free nodes.
      Vector zero = Vector::Zero(force.size());
      solver.EnergyAndGradient(springs, force, zero, nullptr, true, false);
      const Matrix k0 = solver.AssembledHessian();
      Vector f_free(k0.rows());
      for (int i = 0; i < static_cast<int>(free.free_index.size()); ++i) {
        if (free.free_index[i] >= 0)
          f_free.segment(dim * free.free_index[i], dim) = force.segment(dim * i, dim);
      }
      const Vector u_linear = k0.ldlt().solve(f_free);
      Vector u = Vector::Zero(force.size());
      ASSERT_TRUE(solver.Solve(springs, force, Vector::Zero(force.size()), u).converged());
      Vector u_free(k0.rows());
      for (int i = 0; i < static_cast<int>(free.free_index.size()); ++i) {
        if (free.free_index[i] >= 0)
          u_free.segment(dim * free.free_index[i], dim) = u.segment(dim * i, dim);
      }
      // The nonlinear correction is of relative order of the strain, here about 1e-8.
      EXPECT_LE((u_free - u_linear).norm(), 1e-6 * u_linear.norm());
    }
  }
}

TEST(Equilibrium, SparseAndBandedBackendsAgree) {
  int mechanisms = 0;
  long null_space = 0;
  for (int dim : {2, 3}) {
    for (std::uint32_t seed : {1u, 2u, 3u}) {
      const Problem p = Problem::Build(testing::JitteredScene(dim, dim == 2 ? 6 : 4, 0.15, seed));
      const std::vector<std::uint8_t> all(p.candidates().size(), 1);
      const ActiveSprings springs = p.SpringsFromMask(all);
      EquilibriumOptions banded_options, sparse_options;
      banded_options.banded_max_dofs = 1 << 30;
      sparse_options.banded_max_dofs = 0;
      for (const PreparedLoadCase& lc : p.load_cases()) {
        EquilibriumSolver banded(p.candidates(), p.free_sets()[lc.free_set], banded_options);
        EquilibriumSolver sparse(p.candidates(), p.free_sets()[lc.free_set], sparse_options);
        ASSERT_EQ(banded.RestMechanismModes(springs), 0);
        ASSERT_EQ(sparse.RestMechanismModes(springs), 0);
        Vector ud = Vector::Zero(lc.force.size()), us = ud;
        const EquilibriumSummary sd = banded.Solve(springs, lc.force, lc.prescribed, ud);
        const EquilibriumSummary ss = sparse.Solve(springs, lc.force, lc.prescribed, us);
        ASSERT_TRUE(sd.converged());
        ASSERT_TRUE(ss.converged());
        EXPECT_EQ(sd.iterations, ss.iterations);
        EXPECT_LE((ud - us).lpNorm<Eigen::Infinity>(), 1e-10 * ud.lpNorm<Eigen::Infinity>());
      }
      // Mechanisms: whatever the backend, the modes are counted by the same simplicial LDLT of
      // the same scaled matrix, so the counts are equal (a search's trajectory must not
      // depend on banded_max_dofs). That LDLT does not pivot: it never counts a mode that is
      // not in the null space (the scaled matrix's eigenvalues at or below the pivot
      // tolerance) and misses few.
      std::vector<std::uint8_t> thinned(all.size(), 0);
      for (std::size_t s = 0; s < thinned.size(); s += 3) thinned[s] = 1;
      const ActiveSprings holes = p.SpringsFromMask(thinned);
      for (const FreeNodes& free : p.free_sets()) {
        EquilibriumSolver banded(p.candidates(), free, banded_options);
        EquilibriumSolver sparse(p.candidates(), free, sparse_options);
        const int modes = banded.RestMechanismModes(holes);
        const Matrix h = banded.AssembledHessian();
        // Scaled as the factorisations scale it (a node without springs has a zero diagonal).
        const Vector scale =
            h.diagonal().unaryExpr([](double d) { return d > 0.0 ? 1.0 / std::sqrt(d) : 1.0; });
        const Eigen::SelfAdjointEigenSolver<Matrix> eigen(scale.asDiagonal() * h *
                                                          scale.asDiagonal());
        const auto zero_eigenvalues =
            (eigen.eigenvalues().array() <= EquilibriumOptions{}.pivot_tolerance).count();
        EXPECT_EQ(modes, sparse.RestMechanismModes(holes));
        EXPECT_LE(modes, zero_eigenvalues);
        EXPECT_EQ(modes > 0, zero_eigenvalues > 0);
        mechanisms += modes;
        null_space += zero_eigenvalues;
      }
    }
  }
  EXPECT_GT(mechanisms, 0) << "a third of the candidates should leave mechanisms";
  EXPECT_GE(mechanisms, null_space - 1) << "of " << null_space << " modes";
}

TEST(Equilibrium, EverySolveIsInForceBalance) {
  for (int dim : {2, 3}) {
    const Problem p = Problem::Build(testing::JitteredScene(dim, 4, 0.2, 5));
    const std::vector<std::uint8_t> all(p.candidates().size(), 1);
    const ActiveSprings springs = p.SpringsFromMask(all);
    for (const PreparedLoadCase& lc : p.load_cases()) {
      EquilibriumSolver solver(p.candidates(), p.free_sets()[lc.free_set]);
      Vector u = Vector::Zero(lc.force.size());
      ASSERT_TRUE(solver.Solve(springs, lc.force, lc.prescribed, u).converged());
      Vector gradient;
      solver.EnergyAndGradient(springs, lc.force, u, &gradient, false, false);
      // The gradient is the net force imbalance on each free node.
      EXPECT_LE(gradient.lpNorm<Eigen::Infinity>(),
                kForceBalance * lc.force.lpNorm<Eigen::Infinity>());
    }
  }
}

// Chord steps (EquilibriumOptions::chord_contraction): a load step solved from the previous
// step's tangent, factorised by another solver, reaches exact Newton's equilibrium to the
// solve's tolerance with fewer factorisations; with the option at 0 (the default) the start
// tangent is ignored and every step factorises. The loads move the mesh by about a tenth of its
// size, where the springs' turning shows (the response is checked to be nonlinear).
TEST(Equilibrium, ChordStepsFromTheLastLoadStepsTangentReachNewtonsEquilibrium) {
  const Problem p = Problem::Build(testing::JitteredScene(2, 8, 0.2, 5));
  const std::vector<std::uint8_t> all(p.candidates().size(), 1);
  const ActiveSprings springs = p.SpringsFromMask(all);
  const PreparedLoadCase& lc = p.load_cases().front();
  const FreeNodes& free = p.free_sets()[lc.free_set];
  const Vector force = 40.0 * lc.force;
  EquilibriumOptions chord;
  chord.chord_contraction = 0.1;
  // The first load step, with its tangent factorised at its equilibrium.
  EquilibriumSolver first(p.candidates(), free, chord);
  Vector half = Vector::Zero(force.size());
  ASSERT_TRUE(first.Solve(springs, 0.5 * force, lc.prescribed, half).converged());
  ASSERT_TRUE(first.FactorizeTangent(springs, half));
  ASSERT_TRUE(first.HoldsTangent());
  // The second: exact Newton, and chord steps from the first's tangent, from the same start.
  EquilibriumSolver exact(p.candidates(), free);
  EquilibriumSolver chorded(p.candidates(), free, chord);
  Vector u_exact = 2.0 * half, u_chord = 2.0 * half;
  const EquilibriumSummary newton = exact.Solve(springs, force, lc.prescribed, u_exact, &first);
  const EquilibriumSummary steps = chorded.Solve(springs, force, lc.prescribed, u_chord, &first);
  ASSERT_TRUE(newton.converged());
  ASSERT_TRUE(steps.converged());
  EXPECT_EQ(newton.chord_steps, 0);  // the option at 0 ignores a start tangent
  EXPECT_GT(steps.chord_steps, 0);
  // (Here 2 factorisations against Newton's 4.)
  EXPECT_LE(steps.iterations - steps.chord_steps, newton.iterations / 2);
  // Nonlinear: the full load's equilibrium is not twice the half load's.
  EXPECT_GT((u_exact - 2.0 * half).norm(), 1e-3 * u_exact.norm());
  // The same equilibrium, to what the force tolerance resolves.
  EXPECT_LE((u_chord - u_exact).norm(), 1e-8 * u_exact.norm());
  Vector gradient;
  chorded.EnergyAndGradient(springs, force, u_chord, &gradient, false, false);
  EXPECT_LE(gradient.lpNorm<Eigen::Infinity>(), kForceBalance * force.lpNorm<Eigen::Infinity>());
}

TEST(Equilibrium, MechanismsAreCountedNotSolved) {
  // A unit square fixed along its bottom edge, without a diagonal: one shear mode.
  Vector rest(8);
  rest << 0, 0, 1, 0, 1, 1, 0, 1;
  const SpringGeometry square(2, rest, {{0, 1}, {1, 2}, {2, 3}, {0, 3}, {0, 2}});
  EquilibriumSolver solver(square, FreeNodes::FromConstrained(Constrained(4, {0, 1})));
  ActiveSprings no_diagonal{{0, 1, 2, 3}, {1, 1, 1, 1}};
  ActiveSprings braced{{0, 1, 2, 3, 4}, {1, 1, 1, 1, 1}};
  ActiveSprings floating_node{{0, 1}, {1, 1}};  // node 3 has no spring at all
  EXPECT_EQ(solver.RestMechanismModes(no_diagonal), 1);
  EXPECT_EQ(solver.RestMechanismModes(braced), 0);
  EXPECT_EQ(solver.RestMechanismModes(floating_node), 3);
  // Solving a mechanism anyway must not produce NaN.
  Vector force = Vector::Zero(8);
  force[4] = 0.1;
  Vector u = Vector::Zero(8);
  solver.Solve(no_diagonal, force, Vector::Zero(8), u);
  EXPECT_TRUE(u.allFinite());
}

TEST(Equilibrium, NearlyCollinearNodeUnderTransverseLoad) {
  // A node 1e-3 off the line between two fixed nodes, pulled across it: its only transverse
  // stiffness at rest is 2 k eps^2, so Newton starts with a huge step that the line search must
  // tame. At lateral position y the strings pull back with 2 k (L - l) y / L, L = sqrt(1 + y^2),
  // l = sqrt(1 + eps^2).
  const double eps = 1e-3;
  Vector rest(6);
  rest << -1, 0, 1, 0, 0, eps;
  const SpringGeometry g(2, rest, {{0, 2}, {1, 2}});
  EquilibriumSolver solver(g, FreeNodes::FromConstrained(Constrained(3, {0, 1})));
  const ActiveSprings springs = AllSprings(g, 1.0);
  EXPECT_EQ(solver.RestMechanismModes(springs), 0);
  for (double y : {0.05, 0.1, 0.5}) {
    const double L = std::sqrt(1 + y * y), l = std::sqrt(1 + eps * eps);
    Vector force = Vector::Zero(6);
    force[5] = 2 * (L - l) * y / L;
    Vector u = Vector::Zero(6);
    const EquilibriumSummary summary = solver.Solve(springs, force, Vector::Zero(6), u);
    ASSERT_TRUE(summary.converged()) << y;
    // The round-off force floor (1e-12 k l) over the small lateral stiffness bounds the error.
    EXPECT_NEAR(u[5], y - eps, 1e-8 * y);
    EXPECT_NEAR(u[4], 0.0, 1e-12);
  }
}

}  // namespace
}  // namespace springfit
