#include "proto/evaluation_codec.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "engine/runtime/input_error.h"
#include "io/example_catalog.h"

namespace springfit::proto {
namespace {

TEST(EvaluationCodec, CarriesTheRequiredFields) {
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  CostFunction cost(p);
  const Evaluation e = cost.EvaluateMask(std::vector<std::uint8_t>(p.candidates().size(), 1));
  const Json j = EvaluationToJson(p, e);
  EXPECT_DOUBLE_EQ(j["cost"].get<double>(), e.cost);
  EXPECT_DOUBLE_EQ(j["normalized_error"].get<double>(), e.normalized_error);
  EXPECT_EQ(j["mechanism"].get<bool>(), false);
  ASSERT_EQ(j["load_cases"].size(), 7u);
  for (const auto& lc : j["load_cases"]) {
    EXPECT_TRUE(lc.contains("cost"));
    EXPECT_TRUE(lc.contains("iterations"));
    EXPECT_TRUE(lc.contains("residual"));
    EXPECT_EQ(lc["termination"], "converged");
  }
}

TEST(EvaluationCodec, TopologyFilesRoundTripAndRejectNonCandidates) {
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  const std::vector<std::uint8_t> mask = *p.reference_mask();
  EXPECT_EQ(TopologyFromJson(p, TopologyToJson(p, mask)), mask);
  try {
    TopologyFromJson(p, ParseJson(R"({"springs": [[0, 1], [0, 24]]})"));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "springs[1]");
  }
  try {
    TopologyFromJson(p, ParseJson(R"({"springs": [[0, 1], [1, 0]]})"));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "springs[1]");
  }
}

TEST(EvaluationCodec, NonFiniteNumbersAreWrittenAsStringsNotNull) {
  // JSON has no infinity: nlohmann writes null, which reads as "absent". A direct result's
  // pinned spring has confidence +inf (standard error 0).
  EXPECT_EQ(NumberOrText(std::numeric_limits<double>::infinity()).dump(), "\"inf\"");
  EXPECT_EQ(NumberOrText(-std::numeric_limits<double>::infinity()).dump(), "\"-inf\"");
  EXPECT_EQ(NumberOrText(std::nan("")).dump(), "\"nan\"");
  EXPECT_EQ(NumberOrText(1.5).dump(), "1.5");
}

TEST(EvaluationCodec, CarriesNearMechanismModesPerCase) {
  const Problem p = Problem::Build(examples::Make("paper-iso-5x5"));
  CostFunction cost(p);
  const Json j = EvaluationToJson(p, cost.EvaluateMask(*p.reference_mask()));
  for (const Json& c : j["load_cases"]) EXPECT_EQ(c["near_mechanism_modes"], 0);
}

}  // namespace
}  // namespace springfit::proto
