// Round trips of the formats through their text: scenes (every catalogue example and scenes
// with every optional field) compared field by field and written back to the same text;
// results and their trace rows; job records; topology files.
#include <algorithm>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "engine/identification/identify.h"
#include "engine/runtime/input_error.h"
#include "engine/search/search_options.h"
#include "io/example_catalog.h"
#include "proto/evaluation_codec.h"
#include "proto/job.h"
#include "proto/names.h"
#include "proto/outcome_codec.h"
#include "proto/rpc.h"
#include "proto/scene_codec.h"
#include "proto/search_codec.h"
#include "tests/test_scenes.h"

namespace springfit::proto {
namespace {

bool SameVector(const Vector& a, const Vector& b) {
  return a.size() == b.size() && (a.size() == 0 || a == b);
}

void ExpectSameLoads(const std::vector<NodalLoad>& a, const std::vector<NodalLoad>& b,
                     const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (std::size_t m = 0; m < a.size(); ++m) {
    const std::string at = what + "[" + std::to_string(m) + "]";
    EXPECT_EQ(a[m].nodes, b[m].nodes) << at;
    EXPECT_TRUE(SameVector(a[m].value, b[m].value)) << at;
    EXPECT_EQ(a[m].single, b[m].single) << at;
    EXPECT_EQ(a[m].set, b[m].set) << at;
  }
}

// Every field of a Scene, resolved node lists and "as given" flags included.
void ExpectSameScene(const Scene& a, const Scene& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.description, b.description);
  EXPECT_EQ(a.dimension, b.dimension);
  EXPECT_TRUE(SameVector(a.rest, b.rest)) << "rest";

  EXPECT_EQ(a.candidates.kind, b.candidates.kind);
  EXPECT_EQ(a.candidates.spacing, b.candidates.spacing);
  EXPECT_EQ(a.candidates.k, b.candidates.k);
  EXPECT_EQ(a.candidates.radius, b.candidates.radius);
  EXPECT_EQ(a.candidates.pairs, b.candidates.pairs);

  const Reference& ra = a.reference;
  const Reference& rb = b.reference;
  EXPECT_EQ(ra.kind, rb.kind);
  EXPECT_EQ(ra.springs, rb.springs);
  EXPECT_EQ(ra.stiffness, rb.stiffness);
  ASSERT_EQ(ra.positions.size(), rb.positions.size());
  for (std::size_t k = 0; k < ra.positions.size(); ++k)
    EXPECT_TRUE(SameVector(ra.positions[k], rb.positions[k])) << "reference.positions[" << k << "]";
  EXPECT_EQ(ra.fem.elements, rb.fem.elements);
  EXPECT_EQ(ra.fem.materials, rb.fem.materials);
  EXPECT_EQ(ra.fem.element_material, rb.fem.element_material);
  EXPECT_EQ(ra.fem.regions, rb.fem.regions);
  EXPECT_EQ(ra.fem.plane, rb.fem.plane);
  EXPECT_EQ(ra.fem.thickness, rb.fem.thickness);
  EXPECT_EQ(ra.fem.plane_given, rb.fem.plane_given);
  EXPECT_EQ(ra.fem.thickness_given, rb.fem.thickness_given);

  ASSERT_EQ(a.load_cases.size(), b.load_cases.size());
  for (std::size_t k = 0; k < a.load_cases.size(); ++k) {
    const LoadCase& la = a.load_cases[k];
    const LoadCase& lb = b.load_cases[k];
    const std::string at = "load_cases[" + std::to_string(k) + "]";
    EXPECT_EQ(la.name, lb.name) << at;
    EXPECT_EQ(la.fixed, lb.fixed) << at;
    EXPECT_EQ(la.fixed_set, lb.fixed_set) << at;
    ExpectSameLoads(la.forces, lb.forces, at + ".forces");
    ExpectSameLoads(la.displacements, lb.displacements, at + ".displacements");
    ASSERT_EQ(la.tractions.size(), lb.tractions.size()) << at;
    for (std::size_t m = 0; m < la.tractions.size(); ++m) {
      const std::string t = at + ".tractions[" + std::to_string(m) + "]";
      EXPECT_EQ(la.tractions[m].on, lb.tractions[m].on) << t;
      EXPECT_EQ(la.tractions[m].nodes, lb.tractions[m].nodes) << t;
      EXPECT_TRUE(SameVector(la.tractions[m].value, lb.tractions[m].value)) << t;
      EXPECT_EQ(la.tractions[m].total, lb.tractions[m].total) << t;
    }
  }
  EXPECT_EQ(a.node_sets, b.node_sets);
  EXPECT_EQ(a.training_stiffness, b.training_stiffness);

  const SearchSettings& sa = a.search;
  const SearchSettings& sb = b.search;
  EXPECT_EQ(sa.strategy, sb.strategy);
  EXPECT_EQ(sa.identify, sb.identify);
  EXPECT_EQ(sa.seed, sb.seed);
  EXPECT_EQ(sa.population, sb.population);
  EXPECT_EQ(sa.crossover_probability, sb.crossover_probability);
  EXPECT_EQ(sa.mutation_probability, sb.mutation_probability);
  EXPECT_EQ(sa.max_generations, sb.max_generations);
  EXPECT_EQ(sa.max_seconds, sb.max_seconds);
  EXPECT_EQ(sa.stall_generations, sb.stall_generations);
  EXPECT_EQ(sa.target_normalized_error, sb.target_normalized_error);
}

// Writes `scene` as a file would hold it, reads that back (field by field the same scene) and
// writes it again (the same text). Returns the scene read back.
Scene ExpectTextRoundTrip(const Scene& scene) {
  const std::string text = DumpCompact(SceneToJson(scene));
  const Scene back = SceneFromText(text);
  ExpectSameScene(scene, back);
  EXPECT_EQ(DumpCompact(SceneToJson(back)), text);
  return back;
}

TEST(SceneCodecRoundTrip, EveryCatalogueExampleReadsBackFieldByFieldAndWritesTheSameText) {
  int fem_scenes = 0;
  for (const examples::ExampleInfo& info : examples::Catalog()) {
    SCOPED_TRACE(info.name);
    const Scene scene = examples::Make(info.name);
    if (scene.reference.kind == Reference::Kind::kFem) ++fem_scenes;
    ExpectTextRoundTrip(scene);
  }
  EXPECT_GE(fem_scenes, 4)
      << "the FEM examples (plate, kidney, kidney-nl, block) are in the catalogue";
}

// The continuous fit's settings survive a write and a read.
TEST(SceneCodecRoundTrip, TheContinuousFitsSettingsSurvive) {
  Scene scene = examples::Make("fem-plate-5x5");
  scene.search.max_springs = 40;
  scene.search.max_spread = 123.5;
  scene.search.probes = 60;
  const Scene back = ExpectTextRoundTrip(scene);
  EXPECT_EQ(back.search.max_springs, std::optional<int>(40));
  EXPECT_EQ(back.search.max_spread, std::optional<double>(123.5));
  EXPECT_EQ(back.search.probes, std::optional<int>(60));
}

// An FEM reference of two materials by region, plane strain, a thickness, node sets, a
// traction per length, a single-node force, a one-node "nodes" list, a load case without a
// name, a training stiffness and every search setting.
const char* kFemRegions = R"({
  "name": "two-materials",
  "description": "a 2x2-cell plate of two materials",
  "nodes": [[0,0],[1,0],[2,0],[0,1],[1,1],[2,1],[0,2],[1,2],[2,2]],
  "candidates": {"type": "mesh", "k": 3},
  "node_sets": {"top": [6, 7, 8], "bottom": [0, 1, 2], "left": [0, 3, 6], "right": [2, 5, 8]},
  "reference": {"type": "fem",
                "elements": [[0,1,4],[0,4,3],[1,2,5],[1,5,4],[3,4,7],[3,7,6],[4,5,8],[4,8,7]],
                "materials": [{"model": "linear", "young": 10.0, "poisson": 0.3},
                              {"model": "neo_hookean", "young": 2.5, "poisson": 0.45}],
                "element_materials": [0, 1, 0, 1, 1, 0, 0, 1],
                "plane": "strain", "thickness": 0.25},
  "load_cases": [
    {"name": "pull", "fixed": "bottom", "tractions": [{"on": "top", "per_length": [0.125, 0.0625]}]},
    {"name": "push", "fixed": [0, 1, 2], "forces": [{"node": 7, "force": [0.01, 0]}],
     "displacements": [{"nodes": [6], "displacement": [0, 0.001]}]},
    {"fixed": "left", "forces": [{"nodes": "right", "force": [0.02, -0.005]}]}
  ],
  "stiffness": 2.0,
  "search": {"strategy": "hybrid", "identify": "topology", "seed": 18446744073709551615,
             "population": 12, "crossover_probability": 0.7, "mutation_probability": 0.125,
             "max_generations": 77, "max_seconds": 2.5, "stall_generations": 0,
             "target_normalized_error": 1e-6}
})";

TEST(SceneCodecRoundTrip, FemRegionsNodeSetsAndEverySearchSettingSurvive) {
  const Scene s = SceneFromText(kFemRegions);
  // What was read.
  EXPECT_EQ(s.name, "two-materials");
  EXPECT_EQ(s.candidates.kind, CandidateSpec::Kind::kMesh);
  EXPECT_EQ(s.candidates.k, 3);
  EXPECT_EQ(s.node_sets.size(), 4u);
  const FemReference& model = s.reference.fem;
  EXPECT_TRUE(model.regions);
  ASSERT_EQ(model.materials.size(), 2u);
  EXPECT_EQ(model.materials[0], (Material{MaterialModel::kLinear, 10.0, 0.3}));
  EXPECT_EQ(model.materials[1], (Material{MaterialModel::kNeoHookean, 2.5, 0.45}));
  EXPECT_EQ(model.element_material, (std::vector<int>{0, 1, 0, 1, 1, 0, 0, 1}));
  EXPECT_EQ(model.plane, PlaneMode::kStrain);
  EXPECT_TRUE(model.plane_given);
  EXPECT_EQ(model.thickness, 0.25);
  EXPECT_TRUE(model.thickness_given);
  ASSERT_EQ(s.load_cases.size(), 3u);
  const LoadCase& pull = s.load_cases[0];
  EXPECT_EQ(pull.fixed_set, "bottom");
  EXPECT_EQ(pull.fixed, (std::vector<int>{0, 1, 2}));
  ASSERT_EQ(pull.tractions.size(), 1u);
  EXPECT_EQ(pull.tractions[0].on, "top");
  EXPECT_EQ(pull.tractions[0].nodes, (std::vector<int>{6, 7, 8}));
  EXPECT_FALSE(pull.tractions[0].total);
  const LoadCase& push = s.load_cases[1];
  ASSERT_EQ(push.forces.size(), 1u);
  EXPECT_TRUE(push.forces[0].single);
  ASSERT_EQ(push.displacements.size(), 1u);
  EXPECT_FALSE(push.displacements[0].single);
  EXPECT_EQ(push.displacements[0].nodes, std::vector<int>{6});
  const LoadCase& unnamed = s.load_cases[2];
  EXPECT_TRUE(unnamed.name.empty());
  EXPECT_EQ(unnamed.fixed_set, "left");
  ASSERT_EQ(unnamed.forces.size(), 1u);
  EXPECT_EQ(unnamed.forces[0].set, "right");
  EXPECT_EQ(unnamed.forces[0].nodes, (std::vector<int>{2, 5, 8}));
  EXPECT_EQ(s.training_stiffness, std::optional<double>(2.0));
  EXPECT_EQ(s.search.strategy, Strategy::kHybrid);
  EXPECT_EQ(s.search.identify, std::optional<Identify>(Identify::kTopology));
  EXPECT_EQ(s.search.seed, std::numeric_limits<std::uint64_t>::max());
  EXPECT_EQ(s.search.population, std::optional<int>(12));
  EXPECT_EQ(s.search.crossover_probability, std::optional<double>(0.7));
  EXPECT_EQ(s.search.mutation_probability, std::optional<double>(0.125));
  EXPECT_EQ(s.search.max_generations, 77);
  EXPECT_EQ(s.search.max_seconds, std::optional<double>(2.5));
  EXPECT_EQ(s.search.stall_generations, std::optional<int>(0));  // 0 given is not "unset"
  EXPECT_EQ(s.search.target_normalized_error, 1e-6);

  // How it is written: the forms given are kept.
  Json j = SceneToJson(s);
  EXPECT_TRUE(j["reference"].contains("materials"));
  EXPECT_FALSE(j["reference"].contains("material"));
  EXPECT_EQ(j["reference"]["element_materials"], Json::array({0, 1, 0, 1, 1, 0, 0, 1}));
  EXPECT_EQ(j["reference"]["plane"], "strain");
  EXPECT_TRUE(j["load_cases"][0]["tractions"][0].contains("per_length"));
  EXPECT_EQ(j["load_cases"][0]["fixed"], "bottom");
  EXPECT_EQ(j["load_cases"][1]["forces"][0]["node"], 7);
  EXPECT_EQ(j["load_cases"][1]["displacements"][0]["nodes"], Json::array({6}));
  EXPECT_EQ(j["load_cases"][2]["forces"][0]["nodes"], "right");
  EXPECT_FALSE(j["load_cases"][2].contains("name"));
  EXPECT_EQ(j["search"]["stall_generations"], 0);
  EXPECT_EQ(j["search"]["seed"].get<std::uint64_t>(), std::numeric_limits<std::uint64_t>::max());

  ExpectTextRoundTrip(s);
}

// A mass-spring reference with a stiffness per spring, grid candidates with a step per axis, a
// training stiffness, prescribed displacements and a few search settings.
const char* kFullMss = R"({
  "name": "full-mss",
  "nodes": [[0,0],[1,0],[2,0],[0,0.5],[1,0.5],[2,0.5],[0,1],[1,1],[2,1]],
  "candidates": {"type": "grid", "spacing": [1, 0.5]},
  "reference": {"type": "mss",
                "springs": [[0,1],[1,2],[3,4],[4,5],[6,7],[7,8],[0,3],[3,6],
                            [1,4],[4,7],[2,5],[5,8],[0,4],[4,8],[1,5],[3,7]],
                "stiffness": [0.5, 0.75, 1, 1.25, 1.5, 1.75, 2, 2.25,
                              2.5, 2.75, 3, 3.25, 3.5, 3.75, 4, 0.1]},
  "load_cases": [
    {"name": "stretch", "fixed": [0, 1, 2], "forces": [{"nodes": [6, 7, 8], "force": [0, 0.05]}]},
    {"fixed": [0, 3, 6], "forces": [{"node": 8, "force": [0.1, -0.2]}],
     "displacements": [{"node": 2, "displacement": [0.01, 0]},
                       {"nodes": [5], "displacement": [0, -0.003]}]}
  ],
  "stiffness": 1.5,
  "search": {"strategy": "paper", "seed": 0, "max_generations": 5}
})";

TEST(SceneCodecRoundTrip, MassSpringScenesWithEveryCandidateType) {
  const Scene s = SceneFromText(kFullMss);
  EXPECT_EQ(s.candidates.spacing, (std::vector<double>{1.0, 0.5}));
  ASSERT_EQ(s.reference.stiffness.size(), 16u);
  EXPECT_EQ(s.reference.stiffness[15], 0.1);
  EXPECT_EQ(s.training_stiffness, std::optional<double>(1.5));
  EXPECT_EQ(s.search.seed, 0u);
  EXPECT_FALSE(s.search.population.has_value());
  ASSERT_EQ(s.load_cases[1].displacements.size(), 2u);
  EXPECT_TRUE(s.load_cases[1].displacements[0].single);
  EXPECT_FALSE(s.load_cases[1].displacements[1].single);
  ExpectTextRoundTrip(s);

  struct Variant {
    const char* what;
    Json candidates;
  };
  const std::vector<Variant> variants = {
      {"radius", Json::parse(R"({"type": "radius", "radius": 1.25})")},
      {"nearest", Json::parse(R"({"type": "nearest", "k": 4})")},
      // Pairs are kept as written: not reordered, not turned round.
      {"pairs", Json::parse(R"({"type": "pairs", "pairs": [[1, 0], [2, 1], [0, 4], [8, 7]]})")},
  };
  for (const Variant& v : variants) {
    SCOPED_TRACE(v.what);
    Json j = ParseJson(kFullMss);
    j["candidates"] = v.candidates;
    const Scene variant = SceneFromJson(j);
    ExpectTextRoundTrip(variant);
    EXPECT_EQ(SceneToJson(variant)["candidates"], v.candidates);
  }
  const Scene pairs = [&] {
    Json j = ParseJson(kFullMss);
    j["candidates"] = variants[2].candidates;
    return SceneFromJson(j);
  }();
  EXPECT_EQ(pairs.candidates.pairs, (std::vector<NodePair>{{1, 0}, {2, 1}, {0, 4}, {8, 7}}));
}

TEST(SceneCodecRoundTrip, GeneratedScenesKeepEveryDoubleExactly) {
  // Measured positions with noise, per-spring stiffness over decades, jittered nodes, 3D: the
  // doubles are arbitrary, and each must come back bit for bit.
  const Scene noisy = examples::WithMeasurementNoise(examples::Make("paper-aniso-5x5"), 0.01, 3);
  ASSERT_EQ(noisy.reference.kind, Reference::Kind::kPositions);
  ASSERT_EQ(noisy.reference.positions.size(), 7u);
  const Scene noisy_back = ExpectTextRoundTrip(noisy);
  EXPECT_TRUE(noisy_back.reference.positions[3] == noisy.reference.positions[3]);
  ExpectTextRoundTrip(examples::ThinnedGrid({4, 4}, 7, 2.0));
  ExpectTextRoundTrip(examples::ThinnedGrid({3, 3, 3}, 5, 3.0));
  ExpectTextRoundTrip(springfit::testing::JitteredScene(2, 4, 0.2, 11));
  ExpectTextRoundTrip(springfit::testing::JitteredScene(3, 3, 0.1, 12));
}

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
  EXPECT_EQ(back.at("options"), SearchOptionsToJson(r.options));
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

void ExpectSameJob(const JobRecord& a, const JobRecord& b) {
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(a.label, b.label);
  EXPECT_EQ(a.priority, b.priority);
  EXPECT_EQ(a.seed, b.seed);
  EXPECT_EQ(a.idempotency_key, b.idempotency_key);
  EXPECT_EQ(a.state, b.state);
  EXPECT_EQ(a.error, b.error);
  EXPECT_EQ(a.scene_name, b.scene_name);
  EXPECT_EQ(a.genes, b.genes);
  EXPECT_EQ(a.strategy, b.strategy);
  EXPECT_EQ(a.max_generations, b.max_generations);
  EXPECT_EQ(a.created_at, b.created_at);
  EXPECT_EQ(a.started_at, b.started_at);
  EXPECT_EQ(a.finished_at, b.finished_at);
  ASSERT_EQ(a.progress.has_value(), b.progress.has_value());
  if (a.progress) {
    EXPECT_TRUE(a.progress->SameSearch(*b.progress));
    EXPECT_EQ(a.progress->wall_seconds, b.progress->wall_seconds);
  }
  EXPECT_EQ(a.checkpoint_generation, b.checkpoint_generation);
  EXPECT_EQ(a.exact, b.exact);
}

TEST(JobCodecRoundTrip, JobRecordsReadBackAsWrittenOnTheWire) {
  JobRecord full;
  full.id = 123456789012;
  full.label = "nightly \"ci\" \xc3\xb1";  // quotes and UTF-8
  full.priority = -7;
  full.seed = std::numeric_limits<std::uint64_t>::max();
  full.idempotency_key = "key-1";
  full.state = JobState::kSucceeded;
  full.scene_name = "paper-aniso-5x5";
  full.genes = 72;
  full.strategy = "paper";
  full.max_generations = 1000;
  full.created_at = 1700000000.125;
  full.started_at = 1700000001.5;
  full.finished_at = 1700000042.0000001;
  TraceRow progress;
  progress.generation = 40;
  progress.wall_seconds = 3.25;
  progress.evaluations = 820;
  progress.cache_hits = 17;
  progress.best_cost = 1e-5;
  progress.best_normalized_error = 2.5e-7;
  progress.mean_cost = 0.3;
  progress.missing = 0;
  progress.extra = 2;
  full.progress = progress;
  full.checkpoint_generation = 0;  // a checkpoint at generation 0 is one: not "none"
  full.exact = false;

  JobRecord failed;
  failed.id = 2;
  failed.label = "";
  failed.state = JobState::kFailed;
  failed.error = "cannot read the job: disk I/O error";
  failed.scene_name = "s";
  failed.strategy = "default";
  failed.created_at = 1.5e9;
  failed.started_at = 1.5e9 + 1;
  failed.finished_at = 1.5e9 + 2;

  JobRecord queued;  // times not yet (null), no progress, no checkpoint, exact unknown
  queued.id = 1;
  queued.scene_name = "q";
  queued.strategy = "hybrid";
  queued.created_at = 1.5e9;

  for (const JobRecord& job : {full, failed, queued}) {
    SCOPED_TRACE("job " + std::to_string(job.id));
    const std::string text = rpc::Serialize(JobToJson(job));
    const JobRecord back = JobFromJson(ParseJson(text));
    ExpectSameJob(job, back);
    EXPECT_EQ(rpc::Serialize(JobToJson(back)), text);
  }
  const Json queued_json = JobToJson(queued);
  EXPECT_TRUE(queued_json.at("started_at").is_null());
  EXPECT_TRUE(queued_json.at("checkpoint_generation").is_null());
  EXPECT_TRUE(queued_json.at("idempotency_key").is_null());
  EXPECT_EQ(JobToJson(full).at("checkpoint_generation"), 0);

  for (const JobState state : {JobState::kPreparing, JobState::kQueued, JobState::kRunning,
                               JobState::kSucceeded, JobState::kFailed, JobState::kCancelled}) {
    EXPECT_EQ(ParseJobState(JobStateName(state)), std::optional<JobState>(state))
        << JobStateName(state);
  }
}

// A client reads what a newer server writes: members it does not know are ignored, in a job,
// its progress row and a job.progress notification's params.
TEST(JobCodecRoundTrip, AReaderIgnoresMembersOfANewerServer) {
  JobRecord job;
  job.id = 7;
  job.scene_name = "s";
  job.strategy = "default";
  job.created_at = 1.5e9;
  TraceRow row;
  row.generation = 3;
  row.best_normalized_error = 0.25;
  job.progress = row;
  Json json = JobToJson(job);
  json["ran"] = "continuous";
  json["verdict"] = {{"usable", true}};
  json["progress"]["phase"] = "probe_fit";
  const JobRecord back = JobFromJson(ParseJson(rpc::Serialize(json)));  // as read off the wire
  EXPECT_EQ(back.id, 7);
  ASSERT_TRUE(back.progress);
  EXPECT_EQ(back.progress->generation, 3);
  Json params = TraceRowToJson(row);
  params["job_id"] = 7;
  params["max_generations"] = 100;
  params["phase"] = "probe_fit";
  EXPECT_EQ(TraceRowFromJson(ParseJson(rpc::Serialize(params)), "params").best_normalized_error,
            0.25);
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

// A verdict reads back with its lines: the doubts of a doubtful one as well as the unmet requests.
TEST(OutcomeCodecRoundTrip, EveryVerdictAndItsLinesReadBack) {
  Outcome o;
  o.verdict = Verdict::kDoubtful;
  o.doubts = {"a soft mode: ...", "unseen loads: ..."};
  o.unmet = {"spring budget not met: ..."};
  o.springs = 80;
  o.rms_error = 0.05;
  const Outcome back = OutcomeFromJson(ParseJson(OutcomeToJson(o).dump()), "outcome");
  EXPECT_EQ(back.verdict, Verdict::kDoubtful);
  EXPECT_EQ(back.doubts, o.doubts);
  EXPECT_EQ(back.unmet, o.unmet);
  EXPECT_EQ(back.springs, 80);
  EXPECT_EQ(OutcomeToJson(back).dump(), OutcomeToJson(o).dump());
  Json bad = OutcomeToJson(o);
  bad["doubts"][1] = 3;
  try {
    OutcomeFromJson(bad, "outcome");
    ADD_FAILURE() << "a doubt that is not a string was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("outcome.doubts[1]"), std::string::npos) << e.what();
  }
}

// The one wording of a job's E (list, the dashboard) and the one test of step-counted progress.
TEST(JobText, ErrorIsTheVerdictsOnceFinishedAndTheBestSoFarWhileRunning) {
  JobRecord job;
  EXPECT_EQ(JobErrorText(job), "-");
  TraceRow row;
  row.best_normalized_error = 0.04;  // E 0.2
  job.progress = row;
  EXPECT_EQ(JobErrorText(job), "0.2~");
  Outcome outcome;
  outcome.rms_error = 0.0123456;
  job.outcome = outcome;
  EXPECT_EQ(JobErrorText(job), "0.0123");
  job.outcome->rms_error.reset();
  EXPECT_EQ(JobErrorText(job), "-");
  EXPECT_TRUE(ProgressCountsSteps("continuous"));
  EXPECT_FALSE(ProgressCountsSteps("hybrid"));
  EXPECT_FALSE(ProgressCountsSteps("default"));
}

}  // namespace
}  // namespace springfit::proto
