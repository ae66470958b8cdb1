// Round trips of a run's outputs through their text (proto/search_codec.h, evaluation_codec.h):
// results and their trace rows, the typed reading of a result, and topology files.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "engine/api/search_options.h"
#include "engine/identification/identify.h"
#include "engine/runtime/input_error.h"
#include "io/example_catalog.h"
#include "proto/evaluation_codec.h"
#include "proto/json_reader.h"
#include "proto/names.h"
#include "proto/rpc.h"
#include "proto/scene_codec.h"
#include "proto/search_codec.h"
#include "tests/test_scenes.h"

namespace springfit::proto {
namespace {

// A 3x3 grid whose reference keeps only the '/' diagonal of each cell (search_test.cpp's).
Scene AnisotropicGrid3() {
  Scene s = springfit::testing::GridScene(2, 3);
  std::vector<NodePair> kept;
  for (const NodePair& p : s.reference.springs) {
    const double dx = s.rest[2 * p.second] - s.rest[2 * p.first];
    const double dy = s.rest[2 * p.second + 1] - s.rest[2 * p.first + 1];
    if (dx * dy < 0.0) continue;
    kept.push_back(p);
  }
  s.reference.springs = kept;
  return s;
}

TEST(ResultCodecRoundTrip, ResultJsonSurvivesEveryTextFormAndItsTraceReadsBack) {
  const Problem p = Problem::Build(AnisotropicGrid3());
  SearchOptions o = StrategyDefaults(Strategy::kPaper, p.gene_count());
  o.seed = 5;
  o.max_generations = 25;
  o.stop_at_target = false;  // every generation runs: a trace of 26 rows
  const IdentificationResult r = RunIdentification(p, o);
  ASSERT_EQ(r.trace.size(), 26u);
  const Json j = ResultToJson(p, r, true);
  ASSERT_TRUE(j.contains("trace"));
  EXPECT_FALSE(ResultToJson(p, r, false).contains("trace"));

  // The wire's one line (job.result), the daemon's stored form, a result file's indented form.
  for (const std::string& text : {rpc::Serialize(j), j.dump(), DumpCompact(j)}) {
    const Json back = ParseJson(text);
    EXPECT_EQ(back, j) << text;
    EXPECT_EQ(rpc::Serialize(back), rpc::Serialize(j));
  }

  const Json back = ParseJson(rpc::Serialize(j));
  const Json& rows = back.at("trace");
  ASSERT_EQ(rows.size(), r.trace.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const TraceRow row = TraceRowFromJson(rows[i], IndexPath("trace", i));
    EXPECT_TRUE(row.SameSearch(r.trace[i])) << "trace[" << i << "]";
    EXPECT_EQ(row.wall_seconds, r.trace[i].wall_seconds) << "trace[" << i << "]";
    EXPECT_EQ(TraceRowToJson(row), rows[i]) << "trace[" << i << "]";
  }
  // The fields a client reads, as computed.
  EXPECT_EQ(back.at("generations").get<int>(), 25);
  EXPECT_EQ(back.at("evaluations").get<std::int64_t>(), r.counters.evaluations);
  EXPECT_EQ(back.at("cache_hits").get<std::int64_t>(), r.counters.cache_hits);
  EXPECT_EQ(back.at("cost").get<double>(), r.evaluation.cost);
  EXPECT_EQ(back.at("normalized_error").get<double>(), r.evaluation.normalized_error);
  EXPECT_EQ(back.at("wall_seconds").get<double>(), r.wall_seconds);
  EXPECT_EQ(back.at("springs"), PairsToJson(r.springs));
  EXPECT_EQ(back.at("stiffness").get<std::vector<double>>(), r.stiffness);
  EXPECT_EQ(back.at("seed").get<std::uint64_t>(), 5u);
  EXPECT_EQ(back.at("options"), RunOptionsToJson(r.options, r.ran, false));
}

// A job.phase beat's fields read back, the phase's time left (eta_seconds) among them, null
// where it has none; a beat without it (an older daemon's) reads as none.
TEST(ResultCodecRoundTrip, APhaseBeatReadsBackWithItsTimeLeft) {
  ProgressBeat beat;
  beat.phase = "probe_fit";
  beat.wall_seconds = 3.5;
  beat.generation = 2;
  beat.evaluations = 7;
  beat.best_normalized_error = 0.01;
  beat.eta_seconds = 12.25;
  for (const double eta : {12.25, std::numeric_limits<double>::quiet_NaN()}) {
    beat.eta_seconds = eta;
    // (Through its text, as a notification reaches a client.)
    const Json j = ParseJson(rpc::Serialize(ProgressBeatToJson(beat)));
    EXPECT_EQ(j.at("eta_seconds").is_null(), std::isnan(eta));
    PhaseBeat back;
    ProgressBeatFromJson(j, "params", back);
    EXPECT_EQ(back.phase, "probe_fit");
    EXPECT_EQ(back.beat.evaluations, 7);
    EXPECT_EQ(std::isnan(back.beat.eta_seconds), std::isnan(eta));
    if (!std::isnan(eta)) EXPECT_EQ(back.beat.eta_seconds, eta);
  }
  Json older = ParseJson(rpc::Serialize(ProgressBeatToJson(beat)));
  older.erase("eta_seconds");
  PhaseBeat back;
  ProgressBeatFromJson(older, "params", back);
  EXPECT_TRUE(std::isnan(back.beat.eta_seconds));
}

// Issue 47: a result's options are those the strategy that ran reads (a continuous job's page
// showed the genetic search's population and crossover), and on the probe fit a regularisation
// of 0 is the continuation's choice, not a strength of 0 beside the one it chose.
TEST(ResultCodecRoundTrip, AResultsOptionsAreTheOnesItsStrategyReads) {
  SearchOptions o;
  o.max_seconds = 30.0;
  o.max_springs = 12;
  for (const Strategy ran :
       {Strategy::kPaper, Strategy::kHybrid, Strategy::kDirect, Strategy::kContinuous}) {
    const Json j = RunOptionsToJson(o, ran, ran == Strategy::kContinuous);
    const bool genetic = ran == Strategy::kPaper || ran == Strategy::kHybrid;
    EXPECT_EQ(j.contains("population") && j.contains("crossover"), genetic) << j.dump();
    EXPECT_EQ(j.contains("probes") && j.contains("max_spread"), ran == Strategy::kContinuous)
        << j.dump();
    EXPECT_EQ(j.at("max_seconds"), 30.0);
    EXPECT_EQ(j.at("max_springs"), 12);
    EXPECT_TRUE(j.contains("load_size")) << j.dump();  // the verdict reads it whatever ran
    EXPECT_EQ(j.contains("target_normalized_error"), ran != Strategy::kContinuous) << j.dump();
  }
  EXPECT_EQ(RunOptionsToJson(o, Strategy::kContinuous, true).at("regularization"), "continuation");
  EXPECT_EQ(RunOptionsToJson(o, Strategy::kContinuous, false).at("regularization"), 0.0);
  o.choose_regularization = true;
  EXPECT_EQ(RunOptionsToJson(o, Strategy::kContinuous, false).at("regularization"), "auto");
  // Every option still reaches the checkpoint's fingerprint, in the order it always had: the
  // fingerprint hashes the text, and a reordering would refuse every stored checkpoint.
  std::vector<std::string> keys;
  const Json every = SearchOptionsToJson(SearchOptions{});
  for (const auto& [key, value] : every.items()) keys.push_back(key);
  EXPECT_EQ(keys, (std::vector<std::string>{
                      "population", "max_generations", "max_seconds", "stall_generations",
                      "target_normalized_error", "max_springs", "target_error", "max_spread",
                      "load_size", "regularization", "probes", "selection", "roulette_exponent",
                      "crossover", "crossover_probability", "mutation_probability", "elites",
                      "initial_density", "local_search"}));
}

// What `render` and `plot` read of a result: the typed StoredResult, from the text a result
// file or job.result carries, equals the run's own result; what is missing or inconsistent is
// named by its path.
TEST(ResultCodecRoundTrip, TheTypedReadingOfAResultIsTheRunsResult) {
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  SearchOptions o = StrategyDefaults(Strategy::kDirect, p.gene_count());
  o.seed = 11;
  const IdentificationResult r = RunIdentification(p, o);
  const StoredResult typed = StoredResultFromJson(ParseJson(DumpCompact(ResultToJson(p, r, true))));
  EXPECT_EQ(typed.scene, "paper-aniso-5x5");
  EXPECT_EQ(typed.strategy, "direct");
  EXPECT_EQ(typed.seed, std::optional<std::uint64_t>(11));
  EXPECT_EQ(typed.genes, std::optional<int>(p.gene_count()));
  EXPECT_EQ(typed.stop, StopReasonName(r.stop));
  EXPECT_EQ(typed.springs, r.springs);
  EXPECT_EQ(typed.stiffness, r.stiffness);
  ASSERT_TRUE(typed.trace);
  ASSERT_EQ(typed.trace->size(), r.trace.size());
  EXPECT_TRUE(typed.trace->front().SameSearch(r.trace.front()));
  EXPECT_FALSE(StoredResultFromJson(ResultToJson(p, r, false)).trace);

  Json no_springs = ResultToJson(p, r, false);
  no_springs.erase("springs");
  try {
    StoredResultFromJson(no_springs);
    ADD_FAILURE() << "a result without springs was read";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "springs");
  }
  // Every pair is read (smaller, larger), whichever way it is written: a spring has no
  // direction, and readers look pairs up among the candidates as they are.
  Json reversed = ResultToJson(p, r, false);
  for (Json& pair : reversed["springs"]) pair = Json::array({pair[1], pair[0]});
  reversed["unidentifiable"] = Json::array({Json::array({3, 0})});
  reversed["identifiability"] = {
      {"analysed", true},
      {"unseen", Json::array({Json::array({5, 2})})},
      {"groups", Json::array({{{"springs", Json::array({Json::array({9, 1})})}}})}};
  const StoredResult ordered = StoredResultFromJson(reversed);
  EXPECT_EQ(ordered.springs, r.springs);
  EXPECT_EQ(ordered.unidentifiable, (std::vector<NodePair>{{0, 3}}));
  EXPECT_EQ(ordered.undetermined, (std::vector<NodePair>{{2, 5}, {1, 9}}));

  Json short_stiffness = ResultToJson(p, r, false);
  short_stiffness["stiffness"].erase(0);
  try {
    StoredResultFromJson(short_stiffness);
    ADD_FAILURE() << "a stiffness list shorter than the springs was read";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "stiffness");
  }
}

TEST(TraceRowCodecRoundTrip, ExtremeValuesAndUnknownCountsSurviveText) {
  std::vector<TraceRow> rows(3);  // rows[0]: the defaults, counts unknown (-1, written null)
  TraceRow& big = rows[1];
  big.generation = std::numeric_limits<int>::max();
  big.wall_seconds = 1e-9;
  big.evaluations = std::numeric_limits<std::int64_t>::max();
  big.cache_hits = (std::int64_t{1} << 53) + 1;  // no double holds it: counts are not doubles
  big.best_cost = std::numeric_limits<double>::max();
  big.best_normalized_error = std::numeric_limits<double>::denorm_min();
  big.mean_cost = 1.0 / 3.0;
  big.missing = 0;  // known and zero: not null
  big.extra = std::numeric_limits<int>::max();
  TraceRow& mixed = rows[2];
  mixed.generation = 17;
  mixed.wall_seconds = 12345.678901234567;
  mixed.evaluations = 360;
  mixed.best_cost = 0.1;
  mixed.best_normalized_error = std::numeric_limits<double>::min();
  mixed.mean_cost = 1e300;
  mixed.missing = 3;
  mixed.extra = -1;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    SCOPED_TRACE("row " + std::to_string(i));
    const std::string text = TraceRowToJson(rows[i]).dump();
    const TraceRow back = TraceRowFromJson(ParseJson(text), "row");
    EXPECT_TRUE(back.SameSearch(rows[i])) << text;
    EXPECT_EQ(back.wall_seconds, rows[i].wall_seconds);
    EXPECT_EQ(back.missing, rows[i].missing);
    EXPECT_EQ(back.extra, rows[i].extra);
    EXPECT_EQ(TraceRowToJson(back).dump(), text);
  }
  EXPECT_TRUE(TraceRowToJson(rows[0])["missing"].is_null());
  EXPECT_EQ(TraceRowToJson(rows[1])["missing"], 0);
}

TEST(TopologyCodecRoundTrip, AnyMaskSurvivesATopologyFile) {
  const Problem p = Problem::Build(examples::Make("kidney-2d"));
  const std::size_t n = static_cast<std::size_t>(p.candidates().size());
  std::vector<std::vector<std::uint8_t>> masks = {std::vector<std::uint8_t>(n, 0),
                                                  std::vector<std::uint8_t>(n, 1)};
  springfit::testing::TestRandom random(17);
  for (int m = 0; m < 5; ++m) {
    std::vector<std::uint8_t> mask(n, 0);
    for (std::uint8_t& bit : mask) bit = static_cast<std::uint8_t>(random.Uniform() < 0.3);
    masks.push_back(mask);
  }
  for (std::size_t m = 0; m < masks.size(); ++m) {
    SCOPED_TRACE("mask " + std::to_string(m));
    const std::vector<std::uint8_t>& mask = masks[m];
    const Json written = TopologyToJson(p, mask);
    EXPECT_EQ(written.at("springs").size(),
              static_cast<std::size_t>(std::count(mask.begin(), mask.end(), 1)));
    EXPECT_EQ(TopologyFromJson(p, ParseJson(written.dump())), mask);
    // A file may list the springs in any order and either way round.
    Json turned = Json::array();
    for (const Json& spring : written.at("springs"))
      turned.insert(turned.begin(), Json::array({spring[1], spring[0]}));
    Json file;
    file["springs"] = turned;
    EXPECT_EQ(TopologyFromJson(p, ParseJson(file.dump())), mask);
  }
}

// The nonlinear fit's notes, the words the run's summary and the dashboard share: what it left
// out (folds, memory) and what it did not find, each only when it happened.
TEST(NonlinearFitNotes, SayWhatTheStageLeftOutInTheRunsAndTheDashboardsWords) {
  EXPECT_EQ(NonlinearFitNotes(Json{{"fitted_left_out", 0}, {"left_for_memory", 0}, {"failed", 0}}),
            "");
  EXPECT_EQ(NonlinearFitNotes(Json::object()), "");  // (a result from before these counts)
  const Json stage = {{"fitted_left_out", 20},
                      {"left_for_memory", 96},
                      {"case_bytes", 9.2e6},
                      {"max_bytes", 1.5e9},
                      {"failed", 6}};
  EXPECT_EQ(NonlinearFitNotes(stage),
            "; 20 fitted equilibria left out (the rest-linear model folds there or has none)"
            "; 96 fitted probes left out for memory (9.2 MB per equilibrium, 1.5 GB allowed)"
            "; 6 choosing equilibria not found (a fold or no equilibrium)");
  // (a bound the named cases alone exceed: the stage kept them, and says so)
  const Json over = {
      {"fitted_cases", 40}, {"left_for_memory", 96}, {"case_bytes", 9.2e6}, {"max_bytes", 1e8}};
  EXPECT_EQ(NonlinearFitNotes(over),
            "; 96 fitted probes left out for memory (9.2 MB per equilibrium, 0.1 GB allowed: the "
            "named cases alone exceed it)");
}

}  // namespace
}  // namespace springfit::proto
