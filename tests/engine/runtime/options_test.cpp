// Every algorithm's Options: the defaults are valid, and a bad field is refused at the
// algorithm's entry with a message naming the struct, the field, the value and the rule.
#include <functional>
#include <string>

#include <gtest/gtest.h>

#include "engine/api/search_options.h"
#include "engine/direct/direct_identification.h"
#include "engine/direct/identifiability.h"
#include "engine/fem/fem_equilibrium.h"
#include "engine/fit/gauss_newton.h"
#include "engine/fit/stiffness_fit.h"
#include "engine/linalg/column_dependencies.h"
#include "engine/model/equilibrium.h"
#include "engine/probe_fit/quadratic_nnls.h"
#include "engine/search/genetic_search.h"
#include "io/example_catalog.h"

namespace springfit {
namespace {

// `call` throws std::invalid_argument whose message contains every part of `expected`.
void ExpectRefused(const std::function<void()>& call, const std::vector<std::string>& expected) {
  try {
    call();
    ADD_FAILURE() << "accepted; expected a refusal mentioning " << expected.front();
  } catch (const std::invalid_argument& e) {
    for (const std::string& part : expected)
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  }
}

TEST(Options, DefaultsAreValid) {
  EXPECT_NO_THROW(EquilibriumOptions{}.Validate());
  EXPECT_NO_THROW(NnlsOptions{}.Validate());
  EXPECT_NO_THROW(RefinementOptions{}.Validate());
  EXPECT_NO_THROW(DirectOptions{}.Validate());
  EXPECT_NO_THROW(IdentifiabilityOptions{}.Validate());
  EXPECT_NO_THROW(ColumnDependencyOptions{}.Validate());
  EXPECT_NO_THROW(fem::FemSolverOptions{}.Validate());
  EXPECT_NO_THROW(GaussNewtonOptions{}.Validate());
  EXPECT_NO_THROW(StiffnessFitOptions{}.Validate());
  for (Strategy s : {Strategy::kPaper, Strategy::kDefault, Strategy::kHybrid, Strategy::kDirect})
    EXPECT_NO_THROW(StrategyDefaults(s, 100).Validate());
}

TEST(Options, EachStructNamesTheFieldTheValueAndTheRule) {
  EquilibriumOptions eq;
  eq.armijo = 0.7;
  ExpectRefused([&] { eq.Validate(); },
                {"EquilibriumOptions::armijo = 0.69999999999999996", "0 < value < 0.5"});
  eq = {};
  eq.rigidity_tolerance = 0.0;  // every round-off singular value would count as rigid
  ExpectRefused([&] { eq.Validate(); }, {"rigidity_tolerance = 0", "0 < value < 1"});

  NnlsOptions nnls;
  nnls.tolerance = 0.0;
  ExpectRefused([&] { nnls.Validate(); }, {"NnlsOptions::tolerance = 0", "0 < value < 1"});

  response::QuadraticNnlsOptions quadratic;
  quadratic.armijo = 0.5;  // (a step must lower q by a share of the prediction below one half)
  ExpectRefused([&] { quadratic.Validate(); },
                {"QuadraticNnlsOptions::armijo = 0.5", "0 < value < 0.5"});
  quadratic = {};
  quadratic.bound_band = 0.0;
  ExpectRefused([&] { quadratic.Validate(); }, {"bound_band = 0", "0 < value < 1"});
  quadratic = {};
  quadratic.max_halvings = 0;
  ExpectRefused([&] { quadratic.Validate(); }, {"max_halvings = 0", "value >= 1"});

  GaussNewtonOptions descent;
  descent.halvings = 0;
  ExpectRefused([&] { descent.Validate(); }, {"GaussNewtonOptions::halvings = 0", "value >= 1"});
  descent = {};
  descent.initial_radius = 1.0;
  ExpectRefused([&] { descent.Validate(); },
                {"GaussNewtonOptions::max_radius = 0", "initial_radius <= value"});

  RefinementOptions refinement;
  refinement.max_iterations = -1;
  ExpectRefused([&] { refinement.Validate(); },
                {"RefinementOptions::max_iterations = -1", "value >= 0"});

  IdentifiabilityOptions identifiability;
  identifiability.dependencies.rank_tolerance = 2.0;
  ExpectRefused([&] { identifiability.Validate(); },
                {"IdentifiabilityOptions::dependencies::rank_tolerance = 2"});

  SearchOptions search = StrategyDefaults(Strategy::kDefault, 50);
  search.tournament_size = search.population + 1;
  ExpectRefused([&] { search.Validate(); },
                {"SearchOptions::tournament_size", "1 <= value <= population"});
  search = StrategyDefaults(Strategy::kPaper, 50);
  search.initial_density_high = 0.25;  // below the low density 0.5
  ExpectRefused([&] { search.Validate(); },
                {"SearchOptions::initial_density_high = 0.25", "initial_density_low <= value"});
  search = StrategyDefaults(Strategy::kPaper, 50);
  search.mutation_probability = 1.5;
  ExpectRefused([&] { search.Validate(); }, {"SearchOptions::mutation_probability = 1.5"});
}

TEST(Options, NestedOptionsAreNamedThroughTheirOwner) {
  DirectOptions direct;
  direct.nnls.refinement_steps = -2;
  ExpectRefused([&] { direct.Validate(); },
                {"DirectOptions::nnls::refinement_steps = -2", "0 <= value <= 100"});
  direct = {};
  direct.refinement.initial_damping = 0.0;
  ExpectRefused([&] { direct.Validate(); }, {"DirectOptions::refinement::initial_damping = 0"});
  direct = {};
  direct.known_stiffness = -3.0;
  ExpectRefused([&] { direct.Validate(); }, {"DirectOptions::known_stiffness = -3"});
}

TEST(Options, AlgorithmsRefuseBadOptionsAtTheirEntry) {
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  DirectOptions direct;
  direct.significance = -1.0;
  ExpectRefused([&] { IdentifyDirect(p, direct); }, {"DirectOptions::significance = -1"});
  SearchOptions search = StrategyDefaults(Strategy::kPaper, p.gene_count());
  search.crossover_probability = -0.1;
  FitnessEvaluator evaluator(p, nullptr);
  ExpectRefused([&] { GeneticSearch(p, search, evaluator); },
                {"SearchOptions::crossover_probability"});
  EquilibriumOptions eq;
  eq.max_iterations = 0;
  ExpectRefused([&] { EquilibriumSolver(p.candidates(), p.free_sets().front(), eq); },
                {"EquilibriumOptions::max_iterations = 0"});
}

}  // namespace
}  // namespace springfit
