// The first-order Gram matrix (engine/probe_fit/compliance_gram.h): the quadratic it stands for,
// and the exact error to first order.
#include <gtest/gtest.h>

#include <cstdlib>
#include <vector>

#include "engine/probe_fit/compliance_gram.h"
#include "engine/probe_fit/probe_bank.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/probe_fit/rest_stiffness.h"
#include "engine/probe_fit/support_system.h"
#include "io/example_catalog.h"

namespace springfit::response {
namespace {

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

}  // namespace
}  // namespace springfit::response
