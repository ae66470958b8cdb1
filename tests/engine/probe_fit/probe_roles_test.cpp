// Probes by role (engine/probe_fit/probe_bank.h, docs/ARCHITECTURE.md "Probes by role"): the
// held-out probes are a type only the certificate reads, every group has a probe of each role, a
// request for fewer probes than that is refused before any work, and so is one whose memory the
// machine does not have.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "engine/api/search_options.h"
#include "engine/examples/catalog.h"
#include "engine/identification/identify.h"
#include "engine/identification/run_bounds.h"
#include "engine/probe_fit/generalization.h"
#include "engine/probe_fit/probe_bank.h"
#include "engine/probe_fit/probe_objective.h"
#include "engine/probe_fit/response_fit.h"
#include "engine/problem/baseline_evaluation.h"
#include "engine/runtime/input_error.h"
#include "io/example_catalog.h"

namespace springfit::response {
namespace {

// What a fit, a choice and a judgement accept: a bank of fitted and choosing probes. The
// held-out probes are none of them, and give their probes to no one but the certificate.
template <typename Bank>
concept Fittable = requires(const Problem& p, const Bank& b, const SparseMatrix& k,
                            const std::vector<double>& prior, const ResponseFitOptions& o) {
  FitResponse(p, b, k, prior, o);
};
template <typename Bank>
concept Choosable = requires(const Bank& b, const SparseMatrix& k) {
  ChoosingError(b, k);
};
template <typename Bank>
concept Judgeable = requires(const Bank& b, const SparseMatrix& k, const std::vector<bool>& m) {
  ProbeErrorsFor(b, k, m);
};
template <typename T>
concept OpenProbes = requires(const T& t) {
  t.bank_;
};

static_assert(Fittable<ProbeBank> && Choosable<ProbeBank> && Judgeable<ProbeBank>);
static_assert(!Fittable<HeldOutProbes> && !Choosable<HeldOutProbes> && !Judgeable<HeldOutProbes>);
static_assert(!OpenProbes<HeldOutProbes>);
static_assert(!std::is_convertible_v<HeldOutProbes, ProbeBank>);

TEST(ProbeRoles, EveryGroupOfTheSmallestBankHasAProbeOfEachRole) {
  const Problem problem(examples::Make("fem-plate-5x5"));
  const SparseMatrix k = ReferenceRestStiffness(problem);
  ProbeOptions options;
  options.count = MinimumProbeCount(static_cast<int>(problem.free_sets().size()), ProbeOptions{});
  const ProbeBanks banks = MakeProbeBanks(problem, k, options);
  const Certifier certifier(problem, banks.fit, banks.held_out, k);
  const std::vector<double> baseline = *BaselineGeneWeights(problem);
  const Generalization g = certifier.Certify(baseline, SpringRestStiffness(problem, baseline));
  int bases = 0;  // the supports but the pushes' own
  for (const Support& s : banks.fit.supports) bases += s.tool() ? 0 : 1;
  EXPECT_GE(g.held_out, 3 * bases);
  for (std::size_t s = 0; s < banks.fit.supports.size(); ++s) {
    if (banks.fit.supports[s].tool()) continue;
    for (ProbeFamily family : {ProbeFamily::kPoint, ProbeFamily::kPatch, ProbeFamily::kBody}) {
      int fitted = 0, choosing = 0;
      for (const Probe& p : banks.fit.probes) {
        if (p.support != static_cast<int>(s) || p.family != family) continue;
        fitted += p.role == ProbeRole::kFit;
        choosing += p.role == ProbeRole::kSelect;
      }
      EXPECT_GT(fitted, 0) << "support " << s;
      EXPECT_GT(choosing, 0) << "support " << s;
    }
  }
  // A choosing error exists (it was NaN when a group had no choosing probe).
  EXPECT_TRUE(std::isfinite(ChoosingError(banks.fit, SpringRestStiffness(problem, baseline))));
}

TEST(ProbeRoles, TooFewProbesAreRefusedBeforeAnyWork) {
  Scene scene = examples::Make("fem-kidney-2d");
  const Problem problem(scene);
  const int minimum =
      MinimumProbeCount(static_cast<int>(problem.free_sets().size()), ProbeOptions{});
  for (int count : {4, 8, 12, minimum - 1}) {
    SearchOptions options = ResolveSearchOptions(scene.search, problem.gene_count());
    options.probes = count;
    try {
      RunIdentification(problem, options);
      ADD_FAILURE() << count << " probes were accepted";
    } catch (const InputError& e) {
      EXPECT_EQ(e.path(), "search.probes");
      EXPECT_NE(std::string(e.what()).find("at least " + std::to_string(minimum)),
                std::string::npos)
          << e.what();
    }
  }
  SearchOptions enough = ResolveSearchOptions(scene.search, problem.gene_count());
  enough.probes = minimum;
  EXPECT_NO_THROW(CheckRunBounds(problem, enough));
}

// The memory a probe fit needs is estimated from the mesh and the probes (the tool pushes
// included) and refused with the number; the estimate is linear in the probes.
TEST(ProbeRoles, AProbeFitTooLargeForTheMachineIsRefusedWithItsSize) {
  const Problem problem(examples::Make("fem-block-3d"));
  SearchOptions options = ResolveSearchOptions(problem.scene().search, problem.gene_count());
  options.probes = 20000;
  const double bytes = ProbeFitBytes(problem, options);
  // force, reference, model response and adjoint: 4 flat 3n vectors per probe, at least.
  EXPECT_GE(bytes, 4.0 * 20000 * 3 * problem.scene().node_count() * 8.0);
  options.probes = 10000;
  const double half = ProbeFitBytes(problem, options);
  options.probes = 30000;
  EXPECT_NEAR(ProbeFitBytes(problem, options) - bytes, bytes - half, 1e-9 * bytes);
  // The pushes (ProbeOptions::pushes on each support) come on top of the requested probes.
  EXPECT_GT(half, bytes / 2.0);
  options.probes = 10000;
  try {
    CheckRunBounds(problem, options, /*available_bytes=*/bytes / 4.0);
    ADD_FAILURE() << "a fit of " << half << " bytes fitted in " << bytes / 4.0;
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "search.probes");
    EXPECT_NE(std::string(e.what()).find("GB"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(CheckRunBounds(problem, options, /*available_bytes=*/bytes));
  // No probe fit, nothing to bound.
  options.probes = 0;
  EXPECT_EQ(ProbeFitBytes(problem, options), 0.0);
}

}  // namespace
}  // namespace springfit::response
