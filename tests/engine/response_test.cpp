// The probe fit (engine/probe_fit/): the probe bank, the first-order Gram matrix, the pencil's
// eigenvalue bound, and strategy continuous fitted to probes (issue 31).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <Eigen/Eigenvalues>

#include "engine/fit/stiffness_fit.h"
#include "engine/identification/identify.h"
#include "engine/probe_fit/amplitude_judgement.h"
#include "engine/probe_fit/compliance_gram.h"
#include "engine/probe_fit/generalization.h"
#include "engine/probe_fit/linearized_response.h"
#include "engine/probe_fit/mode_cuts.h"
#include "engine/probe_fit/mode_lift.h"
#include "engine/probe_fit/probe_bank.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/probe_fit/probe_objective.h"
#include "engine/probe_fit/response_fit.h"
#include "engine/probe_fit/rest_stiffness.h"
#include "engine/problem/baseline_evaluation.h"
#include "io/example_catalog.h"
#include "proto/names.h"

namespace springfit::response {
namespace {

// The kidney, its reference stiffness at rest, the default probe bank, and the closed-form
// baseline as the prior.
struct KidneyAtRest {
  Problem problem{examples::Make("fem-kidney-2d")};
  SparseMatrix k = ReferenceRestStiffness(problem);
  ResponseFitOptions options;
  ProbeBanks banks = MakeProbeBanks(problem, k, options.probes);
  std::vector<double> prior = *BaselineGeneWeights(problem);
  const ProbeBank& bank = banks.fit;
  // The certificate of `weights` beside `prior`'s.
  Generalization Certify(const std::vector<double>& weights) const {
    return Certifier(problem, bank, banks.held_out, k)
        .Certify(weights, SpringRestStiffness(problem, prior));
  }
};

TEST(ProbeBank, EverySupportHasEveryFamilyInEveryDirectionAndAHeldOutPart) {
  const Problem problem(examples::Make("fem-plate-5x5"));
  const SparseMatrix k = ReferenceRestStiffness(problem);
  const ProbeBanks banks = MakeProbeBanks(problem, k, ProbeOptions{});
  const ProbeBank& bank = banks.fit;
  ASSERT_GE(bank.supports.size(), 4u);  // the user's two and drawn ones
  // (How many of each group are held out: the certificate's counts, per support and family.)
  EXPECT_GT(banks.held_out.size(), 0);
  int user = 0;
  for (const Support& s : bank.supports) user += s.user;
  EXPECT_EQ(user, 2);
  for (std::size_t s = 0; s < bank.supports.size(); ++s) {
    for (ProbeFamily family : {ProbeFamily::kPoint, ProbeFamily::kPatch, ProbeFamily::kBody}) {
      int count = 0, choosing = 0, fitted = 0;
      Matrix directions = Matrix::Zero(2, 2);  // sum of f f^T over the family's forces
      for (const Probe& p : bank.probes) {
        if (p.support != static_cast<int>(s) || p.family != family) continue;
        ++count;
        choosing += p.role == ProbeRole::kSelect;
        fitted += p.role == ProbeRole::kFit;
        for (int node = 0; node < problem.scene().node_count(); ++node) {
          const Vector f = p.force.segment(2 * node, 2);
          directions += f * f.transpose() / std::max(f.squaredNorm(), 1e-300);
          // No load on a held node.
          if (bank.supports[s].constrained[static_cast<std::size_t>(node)]) {
            EXPECT_EQ(f.norm(), 0.0);
          }
        }
      }
      EXPECT_GT(count, 0) << "support " << s << " family " << proto::ProbeFamilyName(family);
      EXPECT_GT(choosing, 0);
      EXPECT_GT(fitted, 0);
      // Both directions of the plane are loaded.
      const Eigen::SelfAdjointEigenSolver<Matrix> eig(directions);
      EXPECT_GT(eig.eigenvalues()[0], 0.05 * eig.eigenvalues()[1])
          << proto::ProbeFamilyName(family);
    }
  }
  // Same options, same bank.
  const ProbeBank again = MakeProbeBanks(problem, k, ProbeOptions{}).fit;
  ASSERT_EQ(again.probes.size(), bank.probes.size());
  for (std::size_t p = 0; p < bank.probes.size(); ++p) {
    EXPECT_EQ(again.probes[p].force, bank.probes[p].force);
    EXPECT_EQ(again.probes[p].role, bank.probes[p].role);
  }
}

// The first-order Gram matrix of every `stride`-th probe of a problem's bank, with what it was
// built from.
struct FirstOrder {
  ProbeBank bank;
  GeneSprings springs;
  std::vector<SupportSystem> systems;
  std::vector<Matrix> compliance;
  std::vector<std::size_t> probes;  // the bank's probes in the Gram, parallel to terms
  std::vector<GramTerm> terms;
  Gram gram;
};

FirstOrder FirstOrderOf(const Problem& problem, std::size_t stride) {
  FirstOrder f;
  const SparseMatrix kref = ReferenceRestStiffness(problem);
  f.bank = MakeProbeBanks(problem, kref, ProbeOptions{}).fit;
  f.springs = GeneSpringsOf(problem);
  for (const Support& s : f.bank.supports) {
    f.systems.emplace_back(problem.dimension(), s.constrained);
    EXPECT_TRUE(f.systems.back().Factorize(kref));
    f.compliance.push_back(f.systems.back().Compliance());
  }
  for (std::size_t p = 0; p < f.bank.probes.size(); p += stride) {
    const Probe& probe = f.bank.probes[p];
    const auto s = static_cast<std::size_t>(probe.support);
    GramTerm t;
    t.support = probe.support;
    t.weight = 1.0 / probe.reference_norm2;
    t.elongation = Elongations(f.springs, probe.reference);
    t.target = f.compliance[s] * f.systems[s].Gather(probe.force);
    f.probes.push_back(p);
    f.terms.push_back(t);
  }
  f.gram = BuildGram(f.springs, f.systems, f.compliance, f.terms);
  return f;
}

// The Gram matrix is the quadratic it claims to be: f(k) = sum_p w_p |C (A(u_p) k - f_p)|^2,
// computed here densely for random stiffness.
TEST(ComplianceGram, MatchesTheDenseQuadraticItStandsFor) {
  const Problem problem(examples::Make("fem-plate-5x5"));
  const FirstOrder f = FirstOrderOf(problem, 7);
  std::srand(3);
  for (int trial = 0; trial < 3; ++trial) {
    Vector k = (Vector::Random(f.springs.size()).array() + 1.0).matrix();
    std::vector<double> weights(k.data(), k.data() + k.size());
    const SparseMatrix km = SpringRestStiffness(problem, weights);
    double direct = 0.0;
    for (std::size_t i = 0; i < f.terms.size(); ++i) {
      const Probe& probe = f.bank.probes[f.probes[i]];
      const auto s = static_cast<std::size_t>(probe.support);
      const Vector residual = f.systems[s].Gather(km * probe.reference - probe.force);
      direct += f.terms[i].weight * (f.compliance[s] * residual).squaredNorm();
    }
    EXPECT_NEAR(f.gram.Value(k), direct, 1e-9 * direct);
  }
}

// To first order the Gram's error is the exact one: at the reference stiffness of an MSS
// reference both vanish, and a small change moves them alike.
TEST(ComplianceGram, IsTheExactErrorToFirstOrder) {
  const Problem problem(examples::Make("paper-iso-5x5"));
  const FirstOrder f = FirstOrderOf(problem, 1);
  std::vector<double> reference = problem.ReferenceWeights();
  const Vector kr =
      Eigen::Map<const Vector>(reference.data(), static_cast<Eigen::Index>(reference.size()));
  EXPECT_NEAR(f.gram.Value(kr), 0.0, 1e-10 * f.gram.constant);
  std::vector<bool> all(f.bank.probes.size(), true);
  for (double h : {1e-2, 1e-3}) {
    Vector dk = h * Vector::Ones(kr.size());
    for (Eigen::Index e = 0; e < dk.size(); e += 2) dk[e] = -dk[e];
    std::vector<double> moved(reference);
    for (std::size_t e = 0; e < moved.size(); ++e) moved[e] += dk[static_cast<Eigen::Index>(e)];
    const std::vector<double> errors =
        ProbeErrorsFor(f.bank, SpringRestStiffness(problem, moved), all);
    double exact = 0.0;
    for (double e : errors) exact += e * e;
    EXPECT_NEAR(f.gram.Value(kr + dk), exact, 5.0 * h * exact) << "h " << h;
  }
}

TEST(PencilExtremes, MatchADenseGeneralisedEigensolver) {
  const Problem problem(examples::Make("fem-plate-5x5"));
  const SparseMatrix kref = ReferenceRestStiffness(problem);
  const SparseMatrix kb = SpringRestStiffness(problem, *BaselineGeneWeights(problem));
  const ProbeBank bank = MakeProbeBanks(problem, kref, ProbeOptions{}).fit;
  const Support& support = bank.supports[0];
  const PencilExtremes x = GeneralizedEigenvalueExtremes(kb, kref, support.constrained, 2);
  SupportSystem a(2, support.constrained), b(2, support.constrained);
  a.Factorize(kb);
  b.Factorize(kref);
  const int n = a.free_dofs();
  Matrix A(n, n), B(n, n);
  for (int j = 0; j < n; ++j) {
    A.col(j) = a.Multiply(Vector::Unit(n, j));
    B.col(j) = b.Multiply(Vector::Unit(n, j));
  }
  Eigen::GeneralizedSelfAdjointEigenSolver<Matrix> dense(A, B, Eigen::EigenvaluesOnly);
  EXPECT_NEAR(x.lambda_min, dense.eigenvalues().minCoeff(), 1e-6 * x.lambda_max);
  EXPECT_NEAR(x.lambda_max, dense.eigenvalues().maxCoeff(), 1e-6 * x.lambda_max);
  EXPECT_NEAR(x.Bound(), std::max(1.0 / x.lambda_min - 1.0, 1.0 - 1.0 / x.lambda_max), 1e-12);
}

// The soft modes are generalised eigenvectors: K_model v = lambda K_ref v on the free degrees of
// freedom, the smallest eigenvalue first and equal to SmallestGeneralizedEigenvalue's, nothing
// on the support's nodes.
TEST(PencilExtremes, SoftModesAreTheSmallestGeneralisedEigenpairs) {
  const Problem problem(examples::Make("fem-kidney-2d"));
  const SparseMatrix kref = ReferenceRestStiffness(problem);
  const SparseMatrix kb = SpringRestStiffness(problem, *BaselineGeneWeights(problem));
  const ProbeBank bank = MakeProbeBanks(problem, kref, ProbeOptions{}).fit;
  const Support& support = bank.supports[0];
  SupportSystem reference(2, support.constrained), model(2, support.constrained);
  ASSERT_TRUE(reference.Factorize(kref));
  ASSERT_TRUE(model.Factorize(kb));
  const std::vector<SoftMode> modes = SoftModes(kb, reference, 1.0, 3);
  ASSERT_EQ(modes.size(), 3u);
  EXPECT_EQ(modes[0].lambda, SmallestGeneralizedEigenvalue(kb, reference));
  for (std::size_t i = 0; i < modes.size(); ++i) {
    if (i > 0) {
      EXPECT_GE(modes[i].lambda, modes[i - 1].lambda);
    }
    const Vector v = reference.Gather(modes[i].shape);
    const Vector residual = model.Multiply(v) - modes[i].lambda * reference.Multiply(v);
    EXPECT_LT(residual.norm(), 1e-6 * model.Multiply(v).norm()) << i;
    EXPECT_NEAR(modes[i].shape.squaredNorm(), v.squaredNorm(), 1e-12 * v.squaredNorm());
  }
  EXPECT_TRUE(SoftModes(kb, reference, modes[0].lambda * 0.999, 3).empty());
}

// Many right-hand sides solved in one pass over the factor (blocked_triangular_solve.h) give
// each one's own solve, bit for bit: random columns, a zero one, and one whose leading entries
// are zero (the forward solve skips zero entries).
TEST(SupportSystem, ManyRightHandSidesGiveEachOnesOwnSolveBitForBit) {
  const Problem problem(examples::Make("fem-kidney-2d"));
  const SparseMatrix kref = ReferenceRestStiffness(problem);
  const ProbeBank bank = MakeProbeBanks(problem, kref, ProbeOptions{}).fit;
  SupportSystem system(2, bank.supports[0].constrained);
  ASSERT_TRUE(system.Factorize(kref));
  const int n = system.free_dofs();
  Matrix b = Matrix::Random(n, 19);
  b.col(3).setZero();
  b.col(7).head(n / 2).setZero();
  Matrix together = b;
  system.SolveColumns(together);
  for (Eigen::Index j = 0; j < b.cols(); ++j) {
    Vector alone = b.col(j);
    system.Solve(alone);
    EXPECT_EQ(Vector(together.col(j)), alone) << "column " << j;
  }
  EXPECT_LT((system.Multiply(together.col(0)) - b.col(0)).norm(), 1e-9 * b.col(0).norm());
}

Scene PlateWithOneCase() {
  Scene s = examples::Make("fem-plate-5x5");
  s.load_cases.resize(1);  // stretch +y only: shear and the other support are never loaded
  return s;
}

// A named case that leaves modes unloaded: the model fitted to probes still holds every load
// on the user's support, and does better than the baseline on loads it never saw.
TEST(ProbeFitStrategy, SupportsModesTheNamedCasesLeaveUnloaded) {
  const Problem problem(PlateWithOneCase());
  SearchOptions options = StrategyDefaults(Strategy::kContinuous, problem.gene_count());
  options.strategy = Strategy::kContinuous;
  const IdentificationResult r = RunIdentification(problem, options);
  ASSERT_TRUE(r.generalization);
  const Generalization& g = *r.generalization;
  EXPECT_TRUE(g.fitted_to_probes);
  EXPECT_FALSE(g.returned_baseline);
  EXPECT_GT(g.lambda_min, 0.1);
  EXPECT_LT(g.model_held_out.median, 0.5 * g.baseline_held_out.median);
  EXPECT_TRUE(r.usable());
}

// Lengths, loads and moduli scaled: the same model, its stiffness scaled, the same errors.
TEST(ProbeFitStrategy, ResultDoesNotDependOnUnits) {
  const Scene base = examples::Make("fem-plate-5x5");
  Scene scaled = base;
  // Lengths by 1e-3 (thickness too), moduli by 1e4: 2D forces scale like E t l, spring
  // stiffness like E t, displacements like l.
  const double length = 1e-3, modulus = 1e4, force = length * length * modulus;
  scaled.rest *= length;
  scaled.reference.fem.thickness *= length;
  for (Material& m : scaled.reference.fem.materials) m.young *= modulus;
  for (LoadCase& lc : scaled.load_cases) {
    for (NodalLoad& f : lc.forces) f.value *= force;
    for (NodalLoad& d : lc.displacements) d.value *= length;
    for (Traction& t : lc.tractions) t.value *= t.total ? force : force / length;
  }
  if (scaled.training_stiffness) *scaled.training_stiffness *= modulus * length;
  const Problem a(base), b(scaled);
  SearchOptions options = StrategyDefaults(Strategy::kContinuous, a.gene_count());
  options.strategy = Strategy::kContinuous;
  const IdentificationResult ra = RunIdentification(a, options);
  const IdentificationResult rb = RunIdentification(b, options);
  ASSERT_EQ(ra.best, rb.best);
  // (3e-4, not round-off's 1e-15: the matrix-free fit's conjugate gradients stop on a relative
  // residual, and round-off can tip that test by one iteration, a step that differs by the
  // last iteration's share, up to 1.2e-4 on the plate; the springs are the same.)
  for (std::size_t s = 0; s < ra.stiffness.size(); ++s)
    EXPECT_NEAR(rb.stiffness[s], ra.stiffness[s] * modulus * length, 3e-4 * rb.stiffness[s]);
  EXPECT_NEAR(rb.generalization->model_held_out.median, ra.generalization->model_held_out.median,
              1e-6 * ra.generalization->model_held_out.median);
}

TEST(ProbeFitStrategy, ProbesNoneKeepsTheNamedCaseFit) {
  Scene s = examples::Make("fem-plate-5x5");
  s.search.probes = 0;
  const Problem problem(s);
  SearchOptions options = ResolveSearchOptions(s.search, problem.gene_count());
  options.strategy = Strategy::kContinuous;
  const IdentificationResult r = RunIdentification(problem, options);
  EXPECT_FALSE(r.generalization);
  ASSERT_TRUE(r.continuous);
  EXPECT_GE(r.continuous->path.size(), 2u);
}

}  // namespace
}  // namespace springfit::response

namespace springfit::response {
namespace {

// Supports drawn from a 3D boundary hold every rigid motion: a patch along one edge of the
// block would leave the rotation about it free for every model (the held-out E of
// 1e17), and the closed-form baseline, a sound model, has a finite error on every probe.
TEST(ProbeBank, DrawnSupportsOnA3DBoundaryHoldEveryRigidMotion) {
  const Problem problem(examples::Make("fem-block-3d"));
  const SparseMatrix k = ReferenceRestStiffness(problem);
  const ProbeBanks banks = MakeProbeBanks(problem, k, ProbeOptions{});
  const ProbeBank& bank = banks.fit;
  const int d = problem.dimension();
  int drawn = 0;
  for (const Support& s : bank.supports) {
    if (s.user) continue;
    ++drawn;
    std::vector<Eigen::Vector3d> held;
    for (int node = 0; node < problem.scene().node_count(); ++node)
      if (s.constrained[static_cast<std::size_t>(node)])
        held.push_back(problem.scene().rest.segment<3>(d * node));
    ASSERT_GE(held.size(), 3u);
    double area = 0.0, longest = 0.0;
    for (const auto& b : held) longest = std::max(longest, (b - held[0]).norm());
    for (const auto& b : held)
      for (const auto& c : held) area = std::max(area, (b - held[0]).cross(c - held[0]).norm());
    EXPECT_GT(area, 0.05 * longest * longest) << s.description;
  }
  EXPECT_GE(drawn, 1);
  const std::optional<std::vector<double>> baseline = BaselineGeneWeights(problem);
  ASSERT_TRUE(baseline);
  const SparseMatrix baseline_k = SpringRestStiffness(problem, *baseline);
  const Generalization g =
      Certifier(problem, bank, banks.held_out, k).Certify(*baseline, baseline_k);
  EXPECT_TRUE(std::isfinite(g.model_held_out.p95)) << g.model_held_out.p95;
  EXPECT_GT(g.lambda_min, 0.0);
}

// The baseline guarantee on unseen loads also holds where the model is fitted to the named
// cases alone (a target error chooses along their path): on the kidney that model is worse
// than van Gelder's on the held-out probes, so the baseline is returned, and says so.
TEST(ProbeFitStrategy, TheNamedCaseFitGivesWayToTheBaselineWhenWorseOnUnseenLoads) {
  Scene s = examples::Make("fem-kidney-2d");
  s.search.target_error = 1e-9;
  const Problem problem(s);
  const SearchOptions options = ResolveSearchOptions(s.search, problem.gene_count());
  const IdentificationResult r = RunIdentification(problem, options);
  ASSERT_TRUE(r.generalization);
  EXPECT_FALSE(r.generalization->fitted_to_probes);
  EXPECT_TRUE(r.generalization->returned_baseline);
  const std::optional<std::vector<double>> baseline = BaselineGeneWeights(problem);
  ASSERT_TRUE(baseline);
  int baseline_springs = 0;
  for (double w : *baseline) baseline_springs += w > 0.0;
  EXPECT_EQ(static_cast<int>(r.springs.size()), baseline_springs);
  EXPECT_DOUBLE_EQ(r.generalization->model_held_out.rms, r.generalization->baseline_held_out.rms);
  ASSERT_TRUE(r.baseline);
  EXPECT_NEAR(std::sqrt(r.evaluation.normalized_error), r.baseline->rms_error,
              1e-9 * r.baseline->rms_error);
  EXPECT_NE(r.stop_message.find("the closed-form baseline"), std::string::npos) << r.stop_message;
  EXPECT_EQ(r.outcome.verdict, Verdict::kUnmetRequest);  // the target is not met
}

// An example run with the scene's spring budget set to `budget`.
IdentificationResult RunWithinBudget(const char* example, int budget) {
  Scene s = examples::Make(example);
  s.search.max_springs = budget;
  const Problem problem(s);
  return RunIdentification(problem, ResolveSearchOptions(s.search, problem.gene_count()));
}

// The best model within a budget that models can meet (the plate's 5x5 nodes need about 45
// springs to hold every mode); a budget none meets is verdict_test.cpp's.
TEST(ProbeFitStrategy, ASpringBudgetGivesTheBestModelWithinIt) {
  const IdentificationResult r = RunWithinBudget("fem-plate-5x5", 60);
  ASSERT_TRUE(r.generalization);
  // Usable and within its budget (its certificate's bound may still be a doubt: verdict_test).
  EXPECT_TRUE(r.usable()) << r.outcome.Headline();
  EXPECT_TRUE(r.outcome.unmet.empty()) << r.outcome.Headline();
  EXPECT_LE(static_cast<int>(r.springs.size()), 60);
  const auto& path = r.generalization->fit.path;
  const auto& chosen = path[static_cast<std::size_t>(r.generalization->fit.chosen)];
  EXPECT_LE(chosen.springs, 60);
  EXPECT_GT(chosen.lambda_min, 0.0);
  for (const auto& p : path)
    if (p.springs <= 60 && p.lambda_min > 0.0) {
      EXPECT_GE(p.select_error, chosen.select_error);
    }
}

// A budget below the fit's springs and near the mesh's own edge count (the kidney: 384
// springs, 263 mesh edges; 2n - 3 = 195 hold a 2D mesh): the path from the fit's many springs
// alone leaves soft modes on the way down and returned a model with unseen-probe E 0.999
// against the baseline's 0.217; the path from the mesh edges keeps a good one within it.
TEST(ProbeFitStrategy, ABudgetNearTheMeshEdgesKeepsAModelBetterThanTheBaseline) {
  const IdentificationResult r = RunWithinBudget("fem-kidney-2d", 250);
  ASSERT_TRUE(r.generalization);
  EXPECT_TRUE(r.usable()) << r.outcome.Headline();
  EXPECT_TRUE(r.outcome.unmet.empty()) << r.outcome.Headline();
  EXPECT_LE(static_cast<int>(r.springs.size()), 250);
  EXPECT_GT(r.generalization->lambda_min, 0.0);
  EXPECT_LT(r.generalization->model_held_out.median,
            0.5 * r.generalization->baseline_held_out.median);
}

}  // namespace
}  // namespace springfit::response

namespace springfit {
namespace {

// A continuous run whose only model cannot carry the loads says so in its stop reason, and the
// result names the strategy that ran.
TEST(ContinuousStrategyVerdict, AMechanismIsNeverCompleted) {
  Scene s = examples::Make("paper-iso-5x5");
  s.candidates.kind = CandidateSpec::Kind::kPairs;
  s.candidates.pairs.clear();
  for (int row = 0; row < 5; ++row)  // horizontals only: nothing holds a vertical load
    for (int col = 0; col + 1 < 5; ++col)
      s.candidates.pairs.push_back({5 * row + col, 5 * row + col + 1});
  s.search.strategy = Strategy::kContinuous;
  s.search.probes = 0;
  const Problem problem(s);
  const IdentificationResult r =
      RunIdentification(problem, ResolveSearchOptions(s.search, problem.gene_count()));
  EXPECT_EQ(r.ran, Strategy::kContinuous);
  EXPECT_EQ(r.stop, StopReason::kMechanism) << r.stop_message;
  EXPECT_NE(r.stop_message.find("(the run ended: no model with an equilibrium"), std::string::npos)
      << r.stop_message;
  EXPECT_FALSE(r.usable());
}

TEST(ContinuousStrategyVerdict, TheResultNamesTheStrategyThatRan) {
  const Problem fem(examples::Make("fem-plate-5x5"));
  const IdentificationResult r =
      RunIdentification(fem, ResolveSearchOptions(fem.scene().search, fem.gene_count()));
  EXPECT_EQ(r.options.strategy, Strategy::kDefault);
  EXPECT_EQ(r.ran, Strategy::kContinuous);
}

}  // namespace
}  // namespace springfit

namespace springfit::response {
namespace {

// The supports' work runs on the pool: the same model whatever the threads.
// The kidney's probe bank and baseline, fitted with one thread and with a pool of two.
struct KidneyFits : KidneyAtRest {
  ResponseFitResult one, two;
  // `matrix_free`: the default fit; else the dense one (the kidney's genes within
  // dense_max_genes).
  explicit KidneyFits(bool matrix_free = false) {
    options.dense_max_genes = matrix_free ? 0 : problem.gene_count();
    WorkerPool pool(2);
    one = FitResponse(problem, bank, k, prior, options);
    two = FitResponse(problem, bank, k, prior, options, nullptr, {}, &pool);
  }
};

// The kidney's fit to the probes alone leaves a mode at lambda 0.068; the loads along its soft
// modes, fitted too, hold every mode above min_lambda, and the model still generalises.
TEST(ResponseFit, SoftModeProbesHoldEveryModeOfTheKidney) {
  const KidneyFits fits;
  const ResponseFitResult& r = fits.one;
  ResponseFitOptions without = fits.options;
  without.soft_mode_rounds = 0;
  without.lift_soft_modes = false;
  const ResponseFitResult plain = FitResponse(fits.problem, fits.bank, fits.k, fits.prior, without);
  ASSERT_LT(plain.lambda_min, fits.options.min_lambda);  // (what this test is about)
  ASSERT_GE(r.soft_mode_rounds.size(), 2u);
  EXPECT_EQ(r.soft_mode_rounds[0].lambda_min, plain.lambda_min);
  EXPECT_GT(r.soft_mode_rounds[1].probes, 0);
  EXPECT_GE(r.lambda_min, fits.options.min_lambda);
  EXPECT_LE(r.select_error, (1.0 + fits.options.lambda_slack) * plain.select_error);
  const Generalization g = fits.Certify(r.weights);
  EXPECT_GE(g.lambda_min, fits.options.min_lambda);
  EXPECT_LT(g.model_held_out.median, 0.5 * g.baseline_held_out.median);
}

// The mode lift raises every mode the kidney's plain fit leaves soft (lambda 0.068) to
// min_lambda by stiffening present springs only: none added, removed or softened, and few of
// them changed.
TEST(ModeLift, LiftsTheKidneysSoftModesByStiffeningPresentSpringsOnly) {
  const KidneyAtRest kidney;
  ResponseFitOptions options = kidney.options;
  options.dense_max_genes = kidney.problem.gene_count();  // (the dense fit leaves a mode soft)
  options.soft_mode_rounds = 0;
  options.lift_soft_modes = false;
  const ResponseFitResult plain =
      FitResponse(kidney.problem, kidney.bank, kidney.k, kidney.prior, options);
  ASSERT_LT(plain.lambda_min, options.min_lambda);
  std::vector<std::pair<int, SupportSystem>> references;
  for (std::size_t s = 0; s < kidney.bank.supports.size(); ++s) {
    if (!kidney.bank.supports[s].user) continue;
    references.emplace_back(static_cast<int>(s),
                            SupportSystem(2, kidney.bank.supports[s].constrained));
    ASSERT_TRUE(references.back().second.Factorize(kidney.k));
  }
  const ModeLift lift = LiftSoftModes(kidney.problem, plain.weights, PriorScale(kidney.prior),
                                      references, options.lift);
  EXPECT_GE(lift.rounds, 1);
  EXPECT_GT(lift.modes, 0);
  int changed = 0;
  for (std::size_t g = 0; g < plain.weights.size(); ++g) {
    if (plain.weights[g] > 0.0) {
      EXPECT_GE(lift.weights[g], plain.weights[g]) << g;
      changed += lift.weights[g] > plain.weights[g] * (1.0 + 1e-3);
    } else {
      EXPECT_EQ(lift.weights[g], 0.0) << g;
    }
  }
  EXPECT_LT(changed, PresentSprings(plain.weights) / 2);
  const SparseMatrix model = SpringRestStiffness(kidney.problem, lift.weights);
  for (const auto& [s, reference] : references)
    EXPECT_GE(SmallestGeneralizedEigenvalue(model, reference), options.min_lambda) << s;
  // In the fit (step 6) the lift is one more candidate, returned when nearly as good.
  options.lift_soft_modes = true;
  const ResponseFitResult r =
      FitResponse(kidney.problem, kidney.bank, kidney.k, kidney.prior, options);
  ASSERT_EQ(r.soft_mode_rounds.size(), 2u);
  EXPECT_FALSE(r.soft_mode_rounds[0].lifted);
  EXPECT_TRUE(r.soft_mode_rounds[1].lifted);
  EXPECT_EQ(r.soft_mode_chosen, 1);
  EXPECT_EQ(r.weights, lift.weights);
  EXPECT_GE(r.lambda_min, options.min_lambda);
  EXPECT_LE(r.select_error, (1.0 + options.lambda_slack) * plain.select_error);
}

// A bound on the stiffness spread holds for the model returned, by the dense and the
// matrix-free fit, with every mode still held; without it the kidney's model spans more.
TEST(ResponseFit, AStiffnessSpreadBoundHoldsInTheModelReturned) {
  const KidneyAtRest kidney;
  const auto spread = [](const std::vector<double>& w) {
    double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
    for (double k : w)
      if (k > 0.0) lo = std::min(lo, k), hi = std::max(hi, k);
    return hi / lo;
  };
  ResponseFitOptions options = kidney.options;
  const ResponseFitResult free =
      FitResponse(kidney.problem, kidney.bank, kidney.k, kidney.prior, options);
  ASSERT_GT(spread(free.weights), 50.0);
  options.max_spread = 50.0;
  for (const int dense_max : {kidney.problem.gene_count(), 0}) {
    options.dense_max_genes = dense_max;
    const ResponseFitResult r =
        FitResponse(kidney.problem, kidney.bank, kidney.k, kidney.prior, options);
    EXPECT_LE(spread(r.weights), 50.0) << r.method;
    EXPECT_GT(r.lambda_min, 0.0) << r.method;
    EXPECT_LT(r.select_error, kNoModel) << r.method;
  }
}

TEST(ResponseFit, SameModelWithOneOrTwoThreads) {
  const KidneyFits fits;
  EXPECT_EQ(fits.one.weights, fits.two.weights);
  EXPECT_EQ(fits.one.select_error, fits.two.select_error);
}

}  // namespace
}  // namespace springfit::response

namespace springfit::response {
namespace {

// A cut is the Rayleigh quotient of its mode, linear in the stiffness: at the model whose soft
// mode it was made from it gives that mode's eigenvalue; the penalty is zero where every cut is
// met, and its half gradient and half Hessian are those of the penalty (finite differences).
TEST(ModeCuts, ACutIsItsModesRayleighQuotientAndThePenaltyItsSquaredShortfall) {
  const KidneyAtRest kidney;
  const GeneSprings springs = GeneSpringsOf(kidney.problem);
  const Vector scale = PriorScale(kidney.prior);
  // A model soft somewhere: the baseline with every spring of one node's star at a thousandth.
  std::vector<double> weights = kidney.prior;
  const int node = kidney.problem.scene().node_count() / 2;
  for (std::size_t g = 0; g < weights.size(); ++g)
    if (springs.pairs[g].first == node || springs.pairs[g].second == node) weights[g] *= 1e-3;
  const std::size_t user = kidney.bank.supports[0].user ? 0 : 1;
  ASSERT_TRUE(kidney.bank.supports[user].user);
  SupportSystem reference(2, kidney.bank.supports[user].constrained);
  ASSERT_TRUE(reference.Factorize(kidney.k));
  const std::vector<SoftMode> modes =
      SoftModes(SpringRestStiffness(kidney.problem, weights), reference, 0.15, 2);
  ASSERT_EQ(modes.size(), 2u);
  ModeHoldOptions options;
  options.weight = 0.1;
  options.target = 0.15;
  ModeCuts cuts(options, scale);
  for (const SoftMode& mode : modes) cuts.Add(springs, mode, reference);
  Vector x(static_cast<Eigen::Index>(weights.size()));
  for (std::size_t g = 0; g < weights.size(); ++g)
    x[static_cast<Eigen::Index>(g)] = weights[g] / scale[static_cast<Eigen::Index>(g)];
  // Each cut at the model is its mode's eigenvalue (a Ritz pair: its Rayleigh quotient), so the
  // penalty is the sum of their squared shortfalls.
  double shortfalls = 0.0;
  for (const SoftMode& mode : modes) {
    EXPECT_NEAR(ModeSlope(springs, mode, reference).dot(Vector::Map(weights.data(), x.size())),
                mode.lambda, 1e-6 * mode.lambda);
    shortfalls += std::pow(0.15 - mode.lambda, 2);
  }
  EXPECT_NEAR(cuts.Penalty(x), 0.1 * shortfalls, 1e-6 * 0.1 * shortfalls);
  // Finite differences along a random direction.
  std::mt19937_64 random(3);
  std::normal_distribution<double> normal;
  Vector v(x.size());
  for (Eigen::Index e = 0; e < v.size(); ++e) v[e] = normal(random);
  const double h = 1e-6 * x.norm() / v.norm();
  const double slope = (cuts.Penalty(x + h * v) - cuts.Penalty(x - h * v)) / (2.0 * h);
  EXPECT_NEAR(2.0 * cuts.HalfGradient(x).dot(v), slope, 1e-5 * std::abs(slope));
  const double curvature =
      (cuts.Penalty(x + h * v) - 2.0 * cuts.Penalty(x) + cuts.Penalty(x - h * v)) / (h * h);
  EXPECT_NEAR(2.0 * v.dot(cuts.HalfHessianProduct(x, v)), curvature, 1e-3 * curvature);
  for (Eigen::Index e = 0; e < x.size(); e += 37) {
    Vector unit = Vector::Zero(x.size());
    unit[e] = 1.0;
    EXPECT_NEAR(cuts.HalfHessianDiagonal(x)[e], cuts.HalfHessianProduct(x, unit)[e],
                1e-12 * (1.0 + cuts.HalfHessianDiagonal(x)[e]));
  }
  // Stiffened past every cut, the penalty and its derivatives vanish.
  const Vector stiff = 1e3 * x;
  EXPECT_EQ(cuts.Penalty(stiff), 0.0);
  EXPECT_EQ(cuts.HalfGradient(stiff).norm(), 0.0);
  EXPECT_EQ(cuts.HalfHessianProduct(stiff, v).norm(), 0.0);
}

// The held modes keep the matrix-free fit's every model off the modes it met soft: on the
// kidney, without the soft-mode refits and the lift (steps 5 and 6), its weak Tikhonov pulls
// leave a mode below min_lambda without the cuts (lambda 0.069 at 1e-3, 0.054 at 1e-4, and the
// continuation gives up there) and hold every mode with them, down to the weakest pull, whose
// model does better on the choosing probes. (A penalty, not a constraint: the weakest pull's
// model may end a little below, 0.0988 on the kidney at 1% of its size; the chosen one holds.)
TEST(ResponseFit, HeldModesKeepTheKidneysEveryModeWithoutRefitOrLift) {
  const KidneyAtRest kidney;
  ResponseFitOptions options = kidney.options;
  options.dense_max_genes = 0;
  options.soft_mode_rounds = 0;
  options.lift_soft_modes = false;
  const ResponseFitResult held =
      FitResponse(kidney.problem, kidney.bank, kidney.k, kidney.prior, options);
  options.hold.weight = 0.0;
  const ResponseFitResult loose =
      FitResponse(kidney.problem, kidney.bank, kidney.k, kidney.prior, options);
  EXPECT_LT(*std::min_element(loose.regularization_lambda_min.begin(),
                              loose.regularization_lambda_min.end()),
            options.min_lambda);
  ASSERT_EQ(held.regularization_lambda_min.size(), options.regularizations.size());
  for (double lambda : held.regularization_lambda_min) EXPECT_GE(lambda, 0.95 * options.min_lambda);
  EXPECT_GE(held.lambda_min, options.min_lambda);
  EXPECT_LT(held.select_error, loose.select_error);
  const Generalization g = kidney.Certify(held.weights);
  EXPECT_GE(g.lambda_min, options.min_lambda);
  EXPECT_LT(g.model_held_out.median, 0.25 * g.baseline_held_out.median);
}

// The matrix-free fit's operators (linearized_response.h) against finite differences of the
// exact residuals: J^T r is half the objective's gradient, and v^T J^T J v = |J v|^2 with J v the
// residuals' derivative along v; J^T J is symmetric.
TEST(LinearizedResponse, GradientAndNormalProductMatchFiniteDifferences) {
  const Problem problem(examples::Make("fem-plate-5x5"));
  const SparseMatrix k = ReferenceRestStiffness(problem);
  ResponseFitOptions options;
  options.dust = 0.0;
  const ProbeBank bank = MakeProbeBanks(problem, k, options.probes).fit;
  const std::vector<double> prior = *BaselineGeneWeights(problem);
  const ProbeObjective objective(problem, bank, k, prior, options);
  const GeneSprings springs = GeneSpringsOf(problem);
  const Vector x = objective.Scaled(prior);
  // A direction that keeps every present spring present and every absent one absent.
  Vector u(x.size()), v(x.size());
  for (Eigen::Index e = 0; e < x.size(); ++e) {
    u[e] = x[e] > 0.0 ? std::sin(1.0 + 3.0 * static_cast<double>(e)) : 0.0;
    v[e] = x[e] > 0.0 ? std::cos(2.0 + 5.0 * static_cast<double>(e)) : 0.0;
  }
  const auto residuals = [&](const Vector& at) {
    LinearizedResponse l(objective, springs);
    EXPECT_TRUE(l.At(objective.Weights(at)));
    return l.Residuals();
  };
  LinearizedResponse at(objective, springs);
  ASSERT_TRUE(at.At(objective.Weights(x)));
  const double h = 1e-5;
  const Vector jv = (residuals(x + h * v) - residuals(x - h * v)) / (2.0 * h);
  const Vector r = at.Residuals();
  // d/dt |r(x + t v)|^2 = 2 r^T J v = 2 (J^T r)^T v.
  EXPECT_NEAR(at.Gradient().dot(v), r.dot(jv), 1e-6 * std::abs(r.dot(jv)));
  EXPECT_NEAR(v.dot(at.NormalProduct(v)), jv.squaredNorm(), 1e-6 * jv.squaredNorm());
  const double uhv = u.dot(at.NormalProduct(v)), vhu = v.dot(at.NormalProduct(u));
  EXPECT_NEAR(uhv, vhu, 1e-10 * std::abs(uhv) + 1e-14);
  EXPECT_NEAR(at.ResidualNorm2(), r.squaredNorm(), 1e-12 * r.squaredNorm());
  // The diagonal's estimate: positive, and of the order of the exact one on a few genes.
  const Vector diagonal = at.NormalDiagonal(64, 1);
  for (Eigen::Index e = 0; e < x.size(); e += 17) {
    if (!(x[e] > 0.0)) continue;
    Vector unit = Vector::Zero(x.size());
    unit[e] = 1.0;
    const double exact = at.NormalProduct(unit)[e];
    EXPECT_GT(diagonal[e], 0.3 * exact) << e;
    EXPECT_LT(diagonal[e], 3.0 * exact) << e;
  }
}

// The judgements of a linearised model reuse its factorisations, supports matched by index:
// the same choosing error and eigenvalue bound, bit for bit, as factorising anew; on a model
// the linearisation does not hold, its factorisations would give other numbers.
TEST(LinearizedResponse, ItsFactorisationsJudgeItsModelAsFactorisingAnew) {
  const KidneyAtRest kidney;
  const std::vector<double>& prior = kidney.prior;
  const ProbeObjective objective(kidney.problem, kidney.bank, kidney.k, prior, kidney.options);
  const GeneSprings springs = GeneSpringsOf(kidney.problem);
  LinearizedResponse at(objective, springs);
  ASSERT_TRUE(at.At(prior));
  ASSERT_GE(objective.fitted_supports().size(), 2u);
  EXPECT_EQ(objective.SelectError(prior, at.Factorized()), objective.SelectError(prior));
  EXPECT_EQ(objective.LambdaMin(prior, at.Factorized()), objective.LambdaMin(prior));
  std::vector<double> other = prior;
  for (std::size_t e = 0; e < other.size(); e += 3) other[e] *= 2.0;
  EXPECT_NE(objective.SelectError(other, at.Factorized()), objective.SelectError(other));
}

// The matrix-free fit (the default): a model far better than the closed-form baseline on
// held-out probes, the same with one or two threads, within a spring budget too.
TEST(ResponseFit, TheMatrixFreeFitBeatsTheBaselineOnHeldOutProbesWhateverTheThreads) {
  const KidneyFits fits(/*matrix_free=*/true);
  const ResponseFitResult& a = fits.one;
  EXPECT_EQ(a.method, "matrix-free");
  EXPECT_EQ(a.weights, fits.two.weights);
  EXPECT_GT(a.gauss_newton_accepted, 0);
  const Generalization g = fits.Certify(a.weights);
  EXPECT_LT(g.model_held_out.median, 0.5 * g.baseline_held_out.median)
      << g.model_held_out.median << " vs " << g.baseline_held_out.median;
  EXPECT_GT(g.lambda_min, 0.0);
  // The budget's two paths run on the pool as the fit does.
  ResponseFitOptions budget = fits.options;
  budget.max_springs = 280;
  WorkerPool pool(2);
  const ResponseFitResult one = FitResponse(fits.problem, fits.bank, fits.k, fits.prior, budget);
  const ResponseFitResult two =
      FitResponse(fits.problem, fits.bank, fits.k, fits.prior, budget, nullptr, {}, &pool);
  EXPECT_LE(PresentSprings(one.weights), 280);
  EXPECT_EQ(one.weights, two.weights);
}

// The matrix-free fit within a spring budget: the least salient springs out, the rest refitted,
// a model that holds every support within the budget.
TEST(ResponseFit, TheMatrixFreeFitKeepsASpringBudget) {
  const Problem problem(examples::Make("fem-kidney-2d"));
  const SparseMatrix k = ReferenceRestStiffness(problem);
  ResponseFitOptions options;
  options.max_springs = 300;
  const ProbeBank bank = MakeProbeBanks(problem, k, options.probes).fit;
  const std::vector<double> prior = *BaselineGeneWeights(problem);
  const ResponseFitResult r = FitResponse(problem, bank, k, prior, options);
  ASSERT_EQ(r.path.size(), 2u);
  EXPECT_GT(r.path[0].springs, 300);
  EXPECT_EQ(r.chosen, 1);
  EXPECT_LE(PresentSprings(r.weights), 300);
  EXPECT_GT(r.lambda_min, 0.0);
  EXPECT_LT(r.select_error, 2.0 * r.path[0].select_error);
}

// The matrix-free continuation gives up after `continuation_patience` strengths in a row that
// end no better than the best before them. The kidney's choosing errors by strength are 0.219,
// 0.162, 0.123, 0.125, 0.119, 0.109, 0.110: with patience 1 it stops after the fourth, with
// the third's model, and 2 runs every strength.
TEST(ResponseFit, TheMatrixFreeContinuationGivesUpAfterStrengthsThatDoNoBetter) {
  const KidneyAtRest kidney;
  const auto fit = [&](int patience) {
    ResponseFitOptions options = kidney.options;
    options.continuation_patience = patience;
    return FitResponse(kidney.problem, kidney.bank, kidney.k, kidney.prior, options);
  };
  const ResponseFitResult all = fit(0), patient = fit(2), impatient = fit(1);
  ASSERT_EQ(all.regularization_select_errors.size(), 7u);
  ASSERT_GT(all.regularization_select_errors[3], all.regularization_select_errors[2]);
  EXPECT_EQ(patient.regularization_select_errors, all.regularization_select_errors);
  ASSERT_EQ(impatient.regularization_select_errors.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i)
    EXPECT_EQ(impatient.regularization_select_errors[i], all.regularization_select_errors[i]);
  EXPECT_EQ(impatient.select_error,
            *std::min_element(all.regularization_select_errors.begin(),
                              all.regularization_select_errors.begin() + 4));
  EXPECT_GT(impatient.select_error, all.select_error);
  ResponseFitOptions negative;
  negative.continuation_patience = -1;
  EXPECT_THROW(negative.Validate(), std::invalid_argument);
}

// A 3D mesh (fem-block-3d, 6,256 genes) is fitted to probes too.
TEST(ProbeFitStrategy, A3DMeshIsFittedToProbes) {
  const Problem problem(examples::Make("fem-block-3d"));
  const SearchOptions options = ResolveSearchOptions(problem.scene().search, problem.gene_count());
  const IdentificationResult r = RunIdentification(problem, options);
  ASSERT_TRUE(r.generalization);
  const Generalization& g = *r.generalization;
  EXPECT_TRUE(g.fitted_to_probes);
  EXPECT_FALSE(g.returned_baseline);
  EXPECT_EQ(g.fit.method, "matrix-free");
  EXPECT_LT(g.model_held_out.median, 0.5 * g.baseline_held_out.median)
      << g.model_held_out.median << " vs " << g.baseline_held_out.median;
  EXPECT_TRUE(std::isfinite(g.model_held_out.p95));
  EXPECT_LT(std::sqrt(r.evaluation.normalized_error), 0.5 * r.baseline->rms_error);
}

}  // namespace
}  // namespace springfit::response

namespace springfit::response {
namespace {

// The nonlinear judgement (amplitude_judgement.h) on the nonlinear kidney: at a thousandth of
// the named loads' size every response is its rest-linear one, so the errors are the
// certificate's rest-linear errors on the same probes; at their full size the springs and the
// neo-Hookean reference leave that limit; the same numbers on one thread or two.
TEST(AmplitudeJudgement, SmallLoadsGiveTheRestLinearErrorsAndFullOnesDiffer) {
  const Problem problem(examples::Make("fem-kidney-2d-nl"));
  ASSERT_EQ(problem.response(), Response::kNonlinear);
  const SparseMatrix k = ReferenceRestStiffness(problem);
  // Every fourth probe of the fit's bank (the certificate passes its held-out probes and named
  // cases the same way).
  const ProbeBank all = MakeProbeBanks(problem, k, ProbeOptions{}).fit;
  ProbeBank bank = all;
  bank.probes.clear();
  for (std::size_t p = 0; p < all.probes.size(); p += 4) bank.probes.push_back(all.probes[p]);
  const std::vector<double> baseline = *BaselineGeneWeights(problem);
  std::vector<double> model = baseline;  // another model: every other spring twice as stiff
  for (std::size_t g = 0; g < model.size(); g += 2) model[g] *= 2.0;
  AmplitudeOptions options;
  options.amplitudes = {1e-3, 1.0};
  options.max_probes = 1000;  // every probe of the bank
  const std::vector<AmplitudeErrors> judged = JudgeAtAmplitudes(
      problem, bank, ModelOfWeights(problem, model), ModelOfWeights(problem, baseline), options);
  ASSERT_EQ(judged.size(), 2u);

  const std::vector<bool> include(bank.probes.size(), true);
  const ErrorSummary linear_model =
      Summarize(ProbeErrorsFor(bank, SpringRestStiffness(problem, model), include));
  const ErrorSummary linear_baseline =
      Summarize(ProbeErrorsFor(bank, SpringRestStiffness(problem, baseline), include));
  const AmplitudeErrors& small = judged[0];
  EXPECT_EQ(small.reference_failed, 0);
  EXPECT_EQ(small.model.probes, linear_model.probes);
  EXPECT_NEAR(small.model.median, linear_model.median, 1e-2 * linear_model.median);
  EXPECT_NEAR(small.model.p95, linear_model.p95, 1e-2 * linear_model.p95);
  EXPECT_NEAR(small.baseline.rms, linear_baseline.rms, 1e-2 * linear_baseline.rms);
  const AmplitudeErrors& full = judged[1];
  EXPECT_GT(std::abs(full.baseline.rms - small.baseline.rms), 1e-3 * small.baseline.rms);
  EXPECT_EQ(full.model.probes + full.reference_failed, linear_model.probes);

  // At a thousandth of the loads nothing folds.
  EXPECT_EQ(small.model_inverted, 0);
  EXPECT_EQ(small.baseline_inverted, 0);

  WorkerPool pool(2);
  const std::vector<AmplitudeErrors> threaded =
      JudgeAtAmplitudes(problem, bank, ModelOfWeights(problem, model),
                        ModelOfWeights(problem, baseline), options, nullptr, &pool);
  EXPECT_EQ(threaded[1].model.rms, full.model.rms);
  EXPECT_EQ(threaded[1].baseline.median, full.baseline.median);
  EXPECT_EQ(threaded[1].model_inverted, full.model_inverted);
}

// A model that folds the mesh under a probe is counted as inverting an element: the closed-form
// baseline on the kidney at four times the named loads folds under some pushes, and a model
// twice as stiff everywhere folds under fewer.
TEST(AmplitudeJudgement, ModelsThatFoldTheMeshAreCounted) {
  const Problem problem(examples::Make("fem-kidney-2d-nl"));
  const SparseMatrix k = ReferenceRestStiffness(problem);
  const ProbeBank bank = MakeProbeBanks(problem, k, ProbeOptions{}).fit;
  const std::vector<double> baseline = *BaselineGeneWeights(problem);
  std::vector<double> stiffer = baseline;
  for (double& w : stiffer) w *= 2.0;
  AmplitudeOptions options;
  options.amplitudes = {4.0};
  options.max_probes = 1000;
  WorkerPool pool(2);
  const std::vector<AmplitudeErrors> judged =
      JudgeAtAmplitudes(problem, bank, ModelOfWeights(problem, stiffer),
                        ModelOfWeights(problem, baseline), options, nullptr, &pool);
  ASSERT_EQ(judged.size(), 1u);
  EXPECT_GT(judged[0].baseline_inverted, 0);
  EXPECT_LT(judged[0].model_inverted, judged[0].baseline_inverted);
}

// A linear response has nothing to add to the rest-linear certificate.
TEST(AmplitudeJudgement, ALinearResponseIsNotJudgedAgain) {
  const Problem problem(examples::Make("fem-kidney-2d"));
  ASSERT_EQ(problem.response(), Response::kLinear);
  const SparseMatrix k = ReferenceRestStiffness(problem);
  const ProbeBank bank = MakeProbeBanks(problem, k, ProbeOptions{}).fit;
  const SpringModel baseline = ModelOfWeights(problem, *BaselineGeneWeights(problem));
  EXPECT_TRUE(JudgeAtAmplitudes(problem, bank, baseline, baseline).empty());
}

}  // namespace
}  // namespace springfit::response

namespace springfit::response {
namespace {

// What the fits judge every iterate by stops between solves when asked: at 10,000 nodes one
// judgement takes seconds, and a job must stop (and beat) within one.
TEST(ProbeObjective, ItsJudgementsStopBetweenSolvesWhenAsked) {
  const KidneyAtRest kidney;
  const auto& [problem, k, options, banks, prior, bank] = kidney;
  // A poll that asks for the stop at its n-th call (checked every time: period 0).
  const auto judged_until = [&](int n, const std::function<void(const ProbeObjective&)>& judge) {
    int polls = 0;
    Interruption stop([&] { return ++polls >= n; }, 0.0);
    const ProbeObjective objective(problem, bank, k, prior, options, &stop);
    bool stopped = false;
    try {
      judge(objective);
    } catch (const Interrupted&) {
      stopped = true;
    }
    return std::make_pair(stopped, polls);
  };
  const auto select = [&](const ProbeObjective& o) { o.SelectError(prior); };
  const auto lambda = [&](const ProbeObjective& o) { o.LambdaMin(prior); };
  const auto objective = [&](const ProbeObjective& o) { o.Objective(prior, 0.0); };
  for (const auto& judge : {std::function<void(const ProbeObjective&)>(select),
                            std::function<void(const ProbeObjective&)>(lambda),
                            std::function<void(const ProbeObjective&)>(objective)}) {
    const auto [finished_stopped, checks] = judged_until(1000000, judge);
    EXPECT_FALSE(finished_stopped);
    ASSERT_GE(checks, 3);  // checked along the way, not only at the start
    const auto [stopped, polls] = judged_until(checks / 2, judge);
    EXPECT_TRUE(stopped);
    EXPECT_EQ(polls, checks / 2);
  }
  // Within a support too (the fitted probes of one support are dozens of solves).
  EXPECT_GT(judged_until(1000000, objective).second, static_cast<int>(bank.supports.size()));
}

}  // namespace
}  // namespace springfit::response
