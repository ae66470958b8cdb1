// Strategy direct: the force balance, the NNLS solver and exact identification of topology and
// stiffness from an MSS reference.
#include <gtest/gtest.h>

#include <cmath>

#include "engine/direct/direct_identification.h"
#include "engine/examples/catalog.h"
#include "engine/identification/identify.h"
#include "engine/identification/strategy.h"
#include "engine/linalg/nnls.h"
#include "engine/problem/force_balance.h"
#include "engine/runtime/input_error.h"
#include "io/example_catalog.h"
#include "tests/test_scenes.h"

namespace springfit {
namespace {

double MaxRelativeStiffnessError(const Problem& problem, const DirectResult& r) {
  const std::vector<double> truth = problem.ReferenceWeights();
  double worst = 0.0;
  for (std::size_t g = 0; g < truth.size(); ++g) {
    if (truth[g] > 0.0) worst = std::max(worst, std::abs(r.weights[g] - truth[g]) / truth[g]);
  }
  return worst;
}

TEST(ForceBalance, TheReferenceStiffnessSolvesItExactly) {
  const Problem problem = Problem::Build(examples::ThinnedGrid({4, 4}, 3, 2.0));
  const ForceBalance fb = AssembleForceBalance(problem);
  const std::vector<double> truth = problem.ReferenceWeights();
  const Vector w = Eigen::Map<const Vector>(truth.data(), static_cast<Eigen::Index>(truth.size()));
  // A w = b up to the reference equilibrium's own tolerance (relative to the loads).
  EXPECT_LT((fb.a * w - fb.b).norm(), 1e-9 * fb.b.norm());
  EXPECT_EQ(fb.a.cols(), problem.gene_count());
  // One row per free coordinate per load case.
  Eigen::Index rows = 0;
  for (const PreparedLoadCase& lc : problem.load_cases())
    rows += 2 * problem.free_sets()[lc.free_set].count;
  EXPECT_EQ(fb.a.rows(), rows);
}

TEST(Nnls, MatchesTheBestActiveSetOfASmallDenseProblem) {
  // Random 12 x 6 problems whose unconstrained solution has negative components: the NNLS
  // answer must equal the best of all 64 choices of positive set (brute force).
  testing::TestRandom random(7);
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::MatrixXd dense(12, 6);
    Vector b(12);
    for (Eigen::Index i = 0; i < dense.size(); ++i) dense.data()[i] = 2.0 * random.Uniform() - 1.0;
    for (Eigen::Index i = 0; i < b.size(); ++i) b[i] = 2.0 * random.Uniform() - 1.0;
    const SparseMatrix a = dense.sparseView();
    const NnlsResult r = SolveNnls(a, b, std::vector<bool>(6, true));
    ASSERT_TRUE(r.converged);
    EXPECT_GE(r.x.minCoeff(), 0.0);
    // The dense variant (for Jacobians) finds the same solution.
    const NnlsResult d = SolveDenseNnls(dense, b, std::vector<bool>(6, true));
    ASSERT_TRUE(d.converged);
    EXPECT_LT((d.x - r.x).norm(), 1e-12 * (1.0 + r.x.norm())) << "trial " << trial;
    double best = (b).norm();
    for (int set = 1; set < 64; ++set) {
      std::vector<int> cols;
      for (int j = 0; j < 6; ++j) {
        if (set & (1 << j)) cols.push_back(j);
      }
      Eigen::MatrixXd sub(12, static_cast<Eigen::Index>(cols.size()));
      for (std::size_t c = 0; c < cols.size(); ++c)
        sub.col(static_cast<Eigen::Index>(c)) = dense.col(cols[c]);
      const Vector z = sub.colPivHouseholderQr().solve(b);
      if (z.minCoeff() < 0.0) continue;
      best = std::min(best, (sub * z - b).norm());
    }
    EXPECT_NEAR((dense * r.x - b).norm(), best, 1e-12 * (1.0 + best)) << "trial " << trial;
  }
}

TEST(Nnls, HoldsUnusableColumnsAtZero) {
  Eigen::MatrixXd dense(3, 2);
  dense << 1, 0, 0, 1, 0, 0;
  const Vector b = Vector::Ones(3);
  const NnlsResult r = SolveNnls(dense.sparseView(), b, {true, false});
  EXPECT_DOUBLE_EQ(r.x[1], 0.0);
  EXPECT_NEAR(r.x[0], 1.0, 1e-14);
  const NnlsResult d = SolveDenseNnls(dense, b, {true, false});
  EXPECT_DOUBLE_EQ(d.x[1], 0.0);
  EXPECT_NEAR(d.x[0], 1.0, 1e-14);
}

struct DirectCase {
  std::vector<int> grid;
  std::uint64_t seed;
};

// Stable names ("grid5x5_seed1"): by default gtest prints the parameter's bytes, which
// change between builds.
std::string CaseName(const DirectCase& c) {
  std::string name = "grid";
  for (std::size_t a = 0; a < c.grid.size(); ++a) {
    if (a > 0) name += "x";
    name += std::to_string(c.grid[a]);
  }
  return name + "_seed" + std::to_string(c.seed);
}

void PrintTo(const DirectCase& c, std::ostream* os) {
  *os << CaseName(c);
}

class DirectRecovery : public ::testing::TestWithParam<DirectCase> {};

TEST_P(DirectRecovery, TopologyExactlyAndStiffnessTo1e8) {
  // Stiffness over three decades, so that a uniform guess could not pass.
  const Problem problem =
      Problem::Build(examples::ThinnedGrid(GetParam().grid, GetParam().seed, 3.0));
  const DirectResult r = IdentifyDirect(problem);
  const auto difference = problem.CompareWithReference(r.genome);
  ASSERT_TRUE(difference);
  EXPECT_EQ(difference->hamming(), 0);
  EXPECT_TRUE(r.nnls.converged);
  EXPECT_LE(MaxRelativeStiffnessError(problem, r), 1e-8);
  EXPECT_LT(r.force_residual, 1e-9);
  EXPECT_TRUE(r.unseen.empty());
  // Judged by the displacement cost like every strategy: the identified model is the reference.
  EXPECT_LE(r.evaluation.normalized_error, 1e-12);
}

INSTANTIATE_TEST_SUITE_P(Grids, DirectRecovery,
                         ::testing::Values(DirectCase{{5, 5}, 1}, DirectCase{{6, 4}, 2},
                                           DirectCase{{3, 3, 3}, 1}, DirectCase{{4, 3, 3}, 5}),
                         [](const ::testing::TestParamInfo<DirectCase>& param_info) {
                           return CaseName(param_info.param);
                         });

TEST(Direct, RecoversEveryMssExampleTopologyExactly) {
  for (const char* name :
       {"paper-iso-5x5", "paper-aniso-5x5", "kidney-2d", "grid3d-4x4x4", "stiff-2d"}) {
    const Problem problem = Problem::Build(examples::Make(name));
    const DirectResult r = IdentifyDirect(problem);
    EXPECT_EQ(problem.CompareWithReference(r.genome)->hamming(), 0) << name;
    EXPECT_LE(r.evaluation.normalized_error, 1e-12) << name;
  }
}

TEST(Direct, ScalingLengthsAndForcesChangesNothing) {
  const Scene scene = examples::ThinnedGrid({4, 4}, 9, 2.0);
  const DirectResult a = IdentifyDirect(Problem::Build(scene));
  const DirectResult b = IdentifyDirect(Problem::Build(testing::ScaledScene(scene, 1e-3)));
  EXPECT_EQ(a.genome, b.genome);
  for (std::size_t g = 0; g < a.weights.size(); ++g) {
    EXPECT_NEAR(a.weights[g], b.weights[g], 1e-8 * (1.0 + a.weights[g])) << g;
  }
}

TEST(Direct, NoisyPositionsGetStandardErrorsAndConfidences) {
  const Scene clean = examples::Make("paper-iso-5x5");
  const Scene noisy = examples::WithMeasurementNoise(clean, 1e-3, 4);
  EXPECT_EQ(noisy.reference.kind, Reference::Kind::kPositions);
  // The same seed draws the same noise; another seed, other noise.
  EXPECT_EQ(noisy.reference.positions[2],
            examples::WithMeasurementNoise(clean, 1e-3, 4).reference.positions[2]);
  EXPECT_NE(noisy.reference.positions[2],
            examples::WithMeasurementNoise(clean, 1e-3, 5).reference.positions[2]);
  const Problem truth = Problem::Build(clean);
  const Problem problem = Problem::Build(noisy);
  // The noise has the size asked for: 1e-3 of the RMS displacement per coordinate.
  const Vector delta = problem.load_cases()[0].reference - truth.load_cases()[0].reference;
  const double rms_u = std::sqrt(truth.load_cases()[0].reference_norm2 /
                                 problem.free_sets()[problem.load_cases()[0].free_set].count);
  const double rms_noise =
      delta.norm() / std::sqrt(2.0 * problem.free_sets()[problem.load_cases()[0].free_set].count);
  EXPECT_NEAR(rms_noise / rms_u, 1e-3, 0.4e-3);

  const DirectResult r = IdentifyDirect(problem);
  ASSERT_EQ(r.sigma.size(), static_cast<std::size_t>(problem.gene_count()));
  EXPECT_EQ(truth.CompareWithReference(r.genome)->hamming(), 0);
  for (int g = 0; g < problem.gene_count(); ++g) {
    EXPECT_GT(r.sigma[g], 0.0);
    EXPECT_LT(r.sigma[g], 0.1);  // stiffness 1, noise 1e-3
    if (r.genome[g]) {
      EXPECT_GT(r.confidence[g], 0.0);
    }
  }
  // An MSS reference is exact data: no standard errors.
  EXPECT_TRUE(IdentifyDirect(truth).sigma.empty());
}

TEST(Direct, RefinementByTheDisplacementCostUndoesTheNoiseShrinkage) {
  const Scene clean = examples::Make("paper-aniso-5x5");
  const Problem truth = Problem::Build(clean);
  const Problem problem = Problem::Build(examples::WithMeasurementNoise(clean, 3e-3, 2));
  DirectOptions plain;
  plain.refine = false;
  const DirectResult nnls = IdentifyDirect(problem, plain);
  const DirectResult refined = IdentifyDirect(problem);
  ASSERT_TRUE(refined.refined);
  EXPECT_FALSE(nnls.refined);
  EXPECT_GT(refined.refinement_iterations, 0);
  // Reference stiffness 1: the refined weights of the true springs sit closer to it.
  const auto& mask = *truth.reference_genome();
  double nnls_error = 0.0, refined_error = 0.0;
  for (int g = 0; g < problem.gene_count(); ++g) {
    if (!mask[g]) continue;
    nnls_error += std::abs(nnls.weights[g] - 1.0);
    refined_error += std::abs(refined.weights[g] - 1.0);
  }
  EXPECT_LT(refined_error, 0.5 * nnls_error);
  EXPECT_EQ(truth.CompareWithReference(refined.genome)->hamming(), 0);
  // The displacement cost is what it minimised.
  EXPECT_LT(refined.evaluation.cost, nnls.evaluation.cost);
  // Exact data is not refined.
  EXPECT_FALSE(IdentifyDirect(truth).refined);
}

TEST(Direct, KnowingTheStiffnessFindsTheTopologyUnderMoreNoise) {
  // 1% noise on paper-iso-5x5: per-spring stiffness misses springs, the known training
  // stiffness splits the weights into present and absent ones correctly.
  const Scene clean = examples::Make("paper-iso-5x5");
  const Problem truth = Problem::Build(clean);
  const Problem problem = Problem::Build(examples::WithMeasurementNoise(clean, 0.01, 1));
  const DirectResult per_spring = IdentifyDirect(problem);
  DirectOptions known;
  known.known_stiffness = problem.training_stiffness();
  const DirectResult topology = IdentifyDirect(problem, known);
  EXPECT_GT(truth.CompareWithReference(per_spring.genome)->hamming(), 0);
  EXPECT_EQ(truth.CompareWithReference(topology.genome)->hamming(), 0);
  EXPECT_GT(topology.topology_threshold, 0.0);
  EXPECT_EQ(per_spring.topology_threshold, 0.0);
  for (const double k : topology.springs.stiffness) EXPECT_EQ(k, problem.training_stiffness());
  for (int g = 0; g < problem.gene_count(); ++g) {
    EXPECT_EQ(topology.genome[g] == 1, topology.weights[g] > topology.topology_threshold) << g;
  }

  // Exact data: the topology alone, at the training stiffness, without a split.
  known.known_stiffness = 2.0;  // not the reference's 1: the topology is still exact
  const DirectResult exact = IdentifyDirect(truth, known);
  EXPECT_EQ(truth.CompareWithReference(exact.genome)->hamming(), 0);
  EXPECT_EQ(exact.topology_threshold, 0.0);
  for (const double k : exact.springs.stiffness) EXPECT_EQ(k, 2.0);
}

TEST(Direct, SceneIdentifySettingChoosesWhatRunDirectFinds) {
  Scene scene = examples::Make("stiff-2d");  // per-spring reference stiffness
  scene.search.strategy = Strategy::kDirect;
  const Problem both = Problem::Build(scene);
  const IdentificationResult per_spring =
      RunIdentification(both, ResolveSearchOptions(both.scene().search, both.gene_count()));
  EXPECT_EQ(per_spring.options.identify,
            Identify::kTopologyAndStiffness);  // direct's default
  EXPECT_EQ(per_spring.exact(), true);
  EXPECT_LT(per_spring.evaluation.normalized_error, 1e-12);

  scene.search.identify = Identify::kTopology;
  const Problem topology_only = Problem::Build(scene);
  const IdentificationResult uniform = RunIdentification(
      topology_only,
      ResolveSearchOptions(topology_only.scene().search, topology_only.gene_count()));
  EXPECT_EQ(uniform.options.identify, Identify::kTopology);
  EXPECT_EQ(uniform.exact(), true);  // the topology, yes
  for (const double k : uniform.direct->springs.stiffness)
    EXPECT_EQ(k, topology_only.training_stiffness());
  // ... but uniform stiffness does not reproduce a reference whose stiffness varies.
  EXPECT_GT(uniform.evaluation.normalized_error, 1e-6);

  // The genetic strategies only know the training stiffness; default asked for stiffness
  // runs direct.
  scene.search.identify = Identify::kTopologyAndStiffness;
  scene.search.strategy = Strategy::kDefault;
  {
    const Problem runs_direct(scene);
    EXPECT_EQ(ResolvedStrategy(Strategy::kDefault, runs_direct.scene()), Strategy::kDirect);
  }
  for (const Strategy s : {Strategy::kPaper, Strategy::kHybrid}) {
    scene.search.strategy = s;
    try {
      Problem::Build(scene);
      ADD_FAILURE() << "accepted topology_and_stiffness for a GA strategy";
    } catch (const InputError& e) {
      EXPECT_EQ(e.path(), "search.identify");
    }
  }
  scene.search.identify.reset();
  EXPECT_EQ(ResolveSearchOptions(scene.search, 10).identify, Identify::kTopology);
}

TEST(Direct, SpringsUnderTheThresholdAreAddedBackUntilTheModelCarriesTheLoads) {
  // A threshold no weight passes leaves no spring: a mechanism. The guard then adds the
  // fewest springs, largest weights first, that carry every load case.
  const Problem problem =
      Problem::Build(examples::WithMeasurementNoise(examples::Make("paper-aniso-5x5"), 0.01, 1));
  DirectOptions strict;
  strict.significance = 1e9;
  strict.refine = false;
  strict.carry_loads = false;
  const DirectResult none = IdentifyDirect(problem, strict);
  EXPECT_TRUE(none.springs.index.empty());
  EXPECT_TRUE(none.evaluation.mechanism);
  EXPECT_TRUE(none.added_to_carry.empty());

  strict.carry_loads = true;
  const DirectResult carried = IdentifyDirect(problem, strict);
  EXPECT_FALSE(carried.evaluation.mechanism);
  ASSERT_FALSE(carried.added_to_carry.empty());
  ASSERT_EQ(carried.springs.index.size(), carried.added_to_carry.size());
  double smallest_added = HUGE_VAL;
  int weakest = -1;
  for (const int g : carried.added_to_carry) {
    EXPECT_EQ(carried.genome[g], 1);
    if (carried.weights[g] < smallest_added) {
      smallest_added = carried.weights[g];
      weakest = g;
    }
  }
  // Largest weights first: every gene left out weighs no more than the smallest added one;
  // and the fewest: without the weakest added spring the model is a mechanism again.
  for (int g = 0; g < problem.gene_count(); ++g) {
    if (!carried.genome[g]) {
      EXPECT_LE(carried.weights[g], smallest_added) << g;
    }
  }
  ActiveSprings fewer;
  for (std::size_t i = 0; i < carried.springs.index.size(); ++i) {
    if (carried.springs.index[i] == problem.gene_candidates()[weakest]) continue;
    fewer.index.push_back(carried.springs.index[i]);
    fewer.stiffness.push_back(carried.springs.stiffness[i]);
  }
  CostFunction cost(problem);
  EXPECT_TRUE(cost.Evaluate(fewer).mechanism);
}

// The scene with every force replaced by a prescribed displacement of the same nodes, in the
// force's direction: no external force is left on a free node.
Scene DisplacementsOnly(Scene s) {
  for (LoadCase& lc : s.load_cases) {
    for (NodalLoad& f : lc.forces) {
      f.value *= 0.5 / f.value.norm();
      lc.displacements.push_back(f);
    }
    lc.forces.clear();
  }
  return s;
}

TEST(Direct, DisplacementOnlyLoadsFixTheStiffnessUpToOneFactor) {
  // Topology: exact. The pin is a present spring (on kidney-2d the most strained candidates
  // are all absent ones).
  for (const char* name : {"paper-aniso-5x5", "kidney-2d", "grid3d-4x4x4"}) {
    const Problem problem = Problem::Build(DisplacementsOnly(examples::Make(name)));
    const DirectResult topology = IdentifyDirect(problem);
    EXPECT_TRUE(topology.displacement_only) << name;
    ASSERT_GE(topology.pinned_gene, 0) << name;
    EXPECT_GT(problem.ReferenceWeights()[topology.pinned_gene], 0.0) << name;
    EXPECT_EQ(problem.CompareWithReference(topology.genome)->hamming(), 0) << name;
    EXPECT_LT(topology.evaluation.normalized_error, 1e-12) << name;
    EXPECT_LT(topology.force_residual, 1e-9) << name;
  }

  // Stiffness spanning eight decades: every ratio exact, the median at the training stiffness.
  Scene stiff = DisplacementsOnly(examples::Make("stiff-2d"));
  stiff.training_stiffness = 3.0;
  const Problem problem = Problem::Build(stiff);
  const DirectResult r = IdentifyDirect(problem);
  EXPECT_EQ(problem.CompareWithReference(r.genome)->hamming(), 0);
  const std::vector<double> truth = problem.ReferenceWeights();
  std::vector<double> ratio;
  for (int g = 0; g < problem.gene_count(); ++g) {
    if (truth[g] > 0.0) ratio.push_back(r.weights[g] / truth[g]);
  }
  for (const double q : ratio) EXPECT_NEAR(q / ratio.front(), 1.0, 1e-6);
  std::vector<double> k = r.springs.stiffness;
  std::sort(k.begin(), k.end());
  EXPECT_DOUBLE_EQ(k[k.size() / 2], 3.0);
  EXPECT_LT(r.evaluation.normalized_error, 1e-12);

  // Measured positions (0.1% noise): the pin is still a present spring, the topology exact,
  // and the reported weights are in stiffness units (median kept spring at the known 1).
  const Scene clean = DisplacementsOnly(examples::Make("paper-aniso-5x5"));
  const Problem clean_problem = Problem::Build(clean);
  const Problem noisy = Problem::Build(examples::WithMeasurementNoise(clean, 1e-3, 1));
  DirectOptions known;
  known.known_stiffness = 1.0;
  for (const DirectOptions& o : {DirectOptions{}, known}) {
    const DirectResult d = IdentifyDirect(noisy, o);
    ASSERT_GE(d.pinned_gene, 0);
    EXPECT_GT(clean_problem.ReferenceWeights()[d.pinned_gene], 0.0);
    EXPECT_EQ(clean_problem.CompareWithReference(d.genome)->hamming(), 0);
    std::vector<double> kept;
    for (int g = 0; g < noisy.gene_count(); ++g) {
      if (d.genome[g]) kept.push_back(d.weights[g]);
    }
    std::sort(kept.begin(), kept.end());
    EXPECT_NEAR(kept[kept.size() / 2], 1.0, 1e-12);
  }

  // With forces the scale is the data's: nothing is pinned.
  EXPECT_EQ(IdentifyDirect(Problem::Build(examples::Make("stiff-2d"))).pinned_gene, -1);
}

TEST(Hybrid, SeedsTheGeneticSearchWithTheDirectTopology) {
  // Exact data: the seed is the reference, so the GA has nothing left to do.
  Scene scene = examples::Make("paper-aniso-5x5");
  scene.search.strategy = Strategy::kHybrid;
  const Problem exact = Problem::Build(scene);
  const IdentificationResult clean =
      RunIdentification(exact, ResolveSearchOptions(exact.scene().search, exact.gene_count()));
  EXPECT_EQ(clean.stop, StopReason::kTargetReached);
  EXPECT_EQ(clean.generations, 0);
  ASSERT_TRUE(clean.direct_phase);
  EXPECT_EQ(clean.direct_phase->difference->hamming(), 0);
  EXPECT_GE(clean.trace.front().wall_seconds,
            clean.direct_phase->seconds);  // one clock for both phases

  // 1% noise: direct alone misses springs of paper-iso-5x5; seeded, the GA's local search
  // finds the true topology.
  Scene noisy = examples::WithMeasurementNoise(examples::Make("paper-iso-5x5"), 0.01, 1);
  noisy.search.strategy = Strategy::kHybrid;
  noisy.search.max_generations = 40;
  const Problem problem = Problem::Build(noisy);
  const Problem truth = Problem::Build(examples::Make("paper-iso-5x5"));
  const IdentificationResult result = RunIdentification(
      problem, ResolveSearchOptions(problem.scene().search, problem.gene_count()));
  ASSERT_TRUE(result.direct_phase);
  EXPECT_GT(truth.CompareWithReference(IdentifyDirect(problem).genome)->hamming(), 0);
  EXPECT_EQ(truth.CompareWithReference(result.best)->hamming(), 0);
}

TEST(Direct, ASceneWithoutGenesEndsCleanly) {
  // Node 2 hangs on two reference springs that are not candidates; the only candidate joins
  // the two fixed nodes: no genes at all.
  Scene s;
  s.dimension = 2;
  s.rest.resize(6);
  s.rest << 0, 0, 2, 0, 1, 1;
  s.candidates.kind = CandidateSpec::Kind::kPairs;
  s.candidates.pairs = {{0, 1}};
  s.reference.springs = {{0, 2}, {1, 2}};
  s.reference.stiffness = {1.0};
  LoadCase lc;
  lc.fixed = {0, 1};
  NodalLoad f;
  f.nodes = {2};
  f.value = Vector(2);
  f.value << 0.0, 0.05;
  lc.forces = {f};
  s.load_cases = {lc};
  s.search.strategy = Strategy::kDirect;
  const Problem problem = Problem::Build(s);
  ASSERT_EQ(problem.gene_count(), 0);
  const IdentificationResult run = RunIdentification(problem, ResolveSearchOptions(s.search, 0));
  EXPECT_TRUE(run.springs.empty());
  // No spring: a mechanism, and the stop reason says so (it is no answer).
  EXPECT_EQ(run.stop, StopReason::kMechanism);
  EXPECT_TRUE(run.evaluation.mechanism);
  EXPECT_FALSE(run.usable());
}

TEST(Direct, DependentColumnsGiveFiniteWeightsAndNoFalseConvergence) {
  // One load case on a 5x5 grid: 28 combinations of weights no load case tells apart.
  Scene scene = examples::Make("paper-iso-5x5");
  scene.load_cases.resize(1);
  const Problem problem = Problem::Build(scene);
  const DirectResult r = IdentifyDirect(problem);
  for (const double w : r.weights) EXPECT_TRUE(std::isfinite(w) && w >= 0.0);
  EXPECT_TRUE(std::isfinite(r.force_residual));
  // The force balance can still be met (the reference's weights do), so whatever the
  // solver returned must meet it, or say it did not converge.
  if (r.nnls.converged) {
    EXPECT_LT(r.nnls_residual, 1e-6);
  }
}

TEST(Direct, DirectHasTheShapeOfEveryResult) {
  Scene scene = examples::Make("paper-aniso-5x5");
  scene.search.strategy = Strategy::kDirect;
  const Problem problem = Problem::Build(scene);
  const IdentificationResult run = RunIdentification(
      problem, ResolveSearchOptions(problem.scene().search, problem.gene_count()));
  ASSERT_TRUE(run.direct);
  EXPECT_EQ(run.stiffness.size(), run.springs.size());
  EXPECT_NE(run.stop_message.find("target"), std::string::npos) << run.stop_message;
  EXPECT_EQ(run.stop, StopReason::kTargetReached);
  EXPECT_EQ(run.exact(), true);
  ASSERT_EQ(run.trace.size(), 1u);
  EXPECT_EQ(run.trace[0].missing, 0);
  EXPECT_EQ(run.springs.size(), run.direct->springs.stiffness.size());
  EXPECT_EQ(run.generations, 0);
}

}  // namespace
}  // namespace springfit
