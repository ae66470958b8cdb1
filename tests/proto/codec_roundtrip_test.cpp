// Round trips of scenes through their text: every catalogue example and scenes with every
// optional field, compared field by field and written back to the same text. Results, trace
// rows and topology files are result_codec_roundtrip_test.cpp's; job records and verdicts,
// job_codec_roundtrip_test.cpp's.
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "engine/examples/catalog.h"
#include "io/example_catalog.h"
#include "proto/json_reader.h"
#include "proto/scene_codec.h"
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

}  // namespace
}  // namespace springfit::proto
