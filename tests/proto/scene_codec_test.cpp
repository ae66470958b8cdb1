// Reading scenes: every validation rule rejects with a message naming the JSON path.
#include "proto/scene_codec.h"
#include "engine/api/scene.h"

#include <functional>

#include <gtest/gtest.h>

#include "engine/api/problem.h"
#include "engine/runtime/input_error.h"
#include "io/example_catalog.h"

namespace springfit::proto {
namespace {

// A complete, valid 3x3 scene that writes only what it needs.
const char* kMinimal = R"({
  "nodes": [[0,0],[1,0],[2,0],[0,1],[1,1],[2,1],[0,2],[1,2],[2,2]],
  "reference": {"type": "mss", "springs": [[0,1],[1,2],[3,4],[4,5],[6,7],[7,8],[0,3],[3,6],
                                            [1,4],[4,7],[2,5],[5,8],[0,4],[4,8],[1,5],[3,7]]},
  "load_cases": [
    {"name": "stretch", "fixed": [0,1,2], "forces": [{"nodes": [6,7,8], "force": [0,0.05]}]},
    {"name": "shear", "fixed": [0,3,6], "forces": [{"node": 8, "force": [0,0.05]}],
     "displacements": [{"node": 2, "displacement": [0.01, 0]}]}
  ]
})";

struct BadCase {
  const char* what;
  std::function<void(Json&)> mutate;
  const char* path;             // expected InputError::path()
  const char* message_snippet;  // expected in what()
};

std::string ErrorPath(const Json& j, std::string* message) {
  try {
    Problem::Build(SceneFromJson(j));  // candidates and reference are checked when built
  } catch (const InputError& e) {
    *message = e.what();
    return e.path();
  }
  return "<accepted>";
}

TEST(SceneCodec, UnitsRoundTripAndAConsistentModulusIsAccepted) {
  Json j = ParseJson(kMinimal);
  j["units"] = {{"length", "mm"}, {"force", "mN"}, {"modulus", "kPa"}};
  const Scene s = SceneFromJson(j);
  ASSERT_TRUE(s.units);
  EXPECT_EQ(s.units->length, "mm");
  EXPECT_EQ(s.units->force, "mN");
  EXPECT_EQ(s.units->modulus, "kPa");
  EXPECT_EQ(SceneToJson(s)["units"], j["units"]);
  const DerivedUnits d = DeriveUnits(*s.units);
  EXPECT_EQ(d.stiffness, "mN/mm");
  EXPECT_EQ(d.modulus, "kPa");
  EXPECT_EQ(DeriveUnits({"m", "uN", ""}).modulus, "uN/m^2");  // no named unit
  // The mass unit F = m a implies with time in seconds (the unit of a density, a node mass).
  EXPECT_EQ(d.mass, "kg");
  EXPECT_EQ(d.time, "s");
  EXPECT_EQ(DeriveUnits({"mm", "N", ""}).mass, "t");
  EXPECT_EQ(DeriveUnits({"m", "N", ""}).mass, "kg");
  EXPECT_EQ(DeriveUnits({"m", "uN", ""}).mass, "mg");
  EXPECT_EQ(DeriveUnits({"cm", "N", ""}).mass, "N s^2/cm");  // 100 kg: no named unit
  EXPECT_FALSE(SceneFromJson(ParseJson(kMinimal)).units);
}

TEST(SceneCodec, MinimalSceneReadsWithDefaults) {
  const Scene s = SceneFromText(kMinimal);
  EXPECT_EQ(s.dimension, 2);
  EXPECT_EQ(s.node_count(), 9);
  EXPECT_EQ(s.candidates.kind, CandidateSpec::Kind::kGrid);
  EXPECT_EQ(s.reference.stiffness, std::vector<double>{1.0});
  EXPECT_FALSE(s.training_stiffness);
  EXPECT_DOUBLE_EQ(s.EffectiveTrainingStiffness(), 1.0);
  EXPECT_FALSE(s.search.population.has_value());  // the strategy's default
  EXPECT_EQ(s.load_cases[1].forces[0].nodes, std::vector<int>{8});
  EXPECT_TRUE(s.load_cases[1].forces[0].single);
}

TEST(SceneCodec, EveryRuleNamesTheField) {
  const std::vector<BadCase> cases = {
      {"unknown top-level field", [](Json& j) { j["nodez"] = 1; }, "nodez", "unknown field"},
      {"unknown nested field", [](Json& j) { j["load_cases"][0]["forcez"] = Json::array(); },
       "load_cases[0].forcez", "unknown field"},
      {"missing nodes", [](Json& j) { j.erase("nodes"); }, "nodes", "required"},
      {"wrong dimension",
       [](Json& j) {
         j["nodes"][3] = {0, 1, 0};
       },
       "nodes[3]", "expected 2 components"},
      {"4D node",
       [](Json& j) {
         j["nodes"][0] = {0, 0, 0, 0};
       },
       "nodes[0]", "2 or 3"},
      {"non-number coordinate", [](Json& j) { j["nodes"][2][1] = "x"; }, "nodes[2][1]",
       "expected a number"},
      {"infinite coordinate", [](Json& j) { j["nodes"][2][1] = 1e308 * 10; }, "nodes[2][1]",
       "finite"},
      {"same position",
       [](Json& j) {
         j["nodes"][5] = {1, 0};
       },
       "nodes[5]", "same position as nodes[1]"},
      {"spring index out of range", [](Json& j) { j["reference"]["springs"][3][1] = 9; },
       "reference.springs[3][1]", "out of range"},
      {"negative index", [](Json& j) { j["reference"]["springs"][0][0] = -1; },
       "reference.springs[0][0]", "out of range"},
      {"fractional index", [](Json& j) { j["reference"]["springs"][0][0] = 0.5; },
       "reference.springs[0][0]", "expected an integer"},
      {"self spring",
       [](Json& j) {
         j["reference"]["springs"][2] = {4, 4};
       },
       "reference.springs[2]", "self spring"},
      {"duplicate spring",
       [](Json& j) {
         j["reference"]["springs"][2] = {1, 0};
       },
       "reference.springs[2]", "duplicate spring"},
      {"negative stiffness", [](Json& j) { j["reference"]["stiffness"] = -2; },
       "reference.stiffness", "must be > 0"},
      {"negative per-spring stiffness",
       [](Json& j) {
         Json k = Json::array();
         for (int m = 0; m < 16; ++m) k.push_back(m == 7 ? -1.0 : 1.0);
         j["reference"]["stiffness"] = k;
       },
       "reference.stiffness[7]", "must be > 0"},
      {"stiffness count",
       [](Json& j) {
         j["reference"]["stiffness"] = {1, 2};
       },
       "reference.stiffness", "one per spring"},
      {"negative training stiffness", [](Json& j) { j["stiffness"] = -1; }, "stiffness",
       "must be > 0"},
      {"empty load list", [](Json& j) { j["load_cases"] = Json::array(); }, "load_cases",
       "at least one load case"},
      {"fixed out of range", [](Json& j) { j["load_cases"][0]["fixed"][2] = 12; },
       "load_cases[0].fixed[2]", "out of range"},
      {"force node out of range", [](Json& j) { j["load_cases"][1]["forces"][0]["node"] = 99; },
       "load_cases[1].forces[0].node", "out of range"},
      {"force on fixed node", [](Json& j) { j["load_cases"][0]["forces"][0]["nodes"][1] = 1; },
       "load_cases[0].forces[0].nodes[1]", "constrained"},
      {"force dimension",
       [](Json& j) {
         j["load_cases"][0]["forces"][0]["force"] = {0, 0, 1};
       },
       "load_cases[0].forces[0].force", "expected 2 components"},
      {"node and nodes", [](Json& j) { j["load_cases"][1]["forces"][0]["nodes"] = {7}; },
       "load_cases[1].forces[0]", "exactly one of"},
      {"rigid motion free", [](Json& j) { j["load_cases"][0]["fixed"] = {1}; }, "load_cases[0]",
       "rigid motion"},
      // Units (issue 33): known names, and a modulus that is force / length^2.
      {"unknown length unit",
       [](Json& j) {
         j["units"] = {{"length", "inch"}, {"force", "N"}};
       },
       "units.length", "unknown unit 'inch' (expected m, cm, mm, um)"},
      {"units without a force",
       [](Json& j) {
         j["units"] = {{"length", "mm"}};
       },
       "units.force", "required"},
      {"inconsistent modulus",
       [](Json& j) {
         j["units"] = {{"length", "mm"}, {"force", "N"}, {"modulus", "kPa"}};
       },
       "units.modulus",
       "N/mm^2 is MPa, so moduli and forces would be read 1000 times apart; "
       "write modulus 'MPa' or force 'mN'"},
      {"no load",
       [](Json& j) {
         j["load_cases"][0]["forces"][0]["force"] = {0, 0};
       },
       "load_cases[0]", "applies no load"},
      {"fixed and displaced", [](Json& j) { j["load_cases"][1]["displacements"][0]["node"] = 3; },
       "load_cases[1].displacements[0].node", "already fixed"},
      {"unknown candidate type",
       [](Json& j) {
         j["candidates"] = {{"type", "delaunay"}};
       },
       "candidates.type", "unknown candidate type"},
      {"nearest k",
       [](Json& j) {
         j["candidates"] = {{"type", "nearest"}, {"k", 0}};
       },
       "candidates.k", ">= 1"},
      {"radius missing",
       [](Json& j) {
         j["candidates"] = {{"type", "radius"}};
       },
       "candidates.radius", "required"},
      {"option of another type",
       [](Json& j) {
         j["candidates"] = {{"type", "grid"}, {"k", 3}};
       },
       "candidates.k", "only applies"},
      {"candidate pair out of range",
       [](Json& j) {
         j["candidates"] = {{"type", "pairs"}, {"pairs", {{0, 1}, {1, 10}}}};
       },
       "candidates.pairs[1][1]", "out of range"},
      {"grid off lattice",
       [](Json& j) {
         j["nodes"][4] = {1.3, 1};
       },
       "candidates", "off it"},
      {"positions count",
       [](Json& j) {
         j["reference"] = {{"type", "positions"}, {"positions", Json::array()}};
       },
       "reference.positions", "one configuration per load case"},
      {"unknown strategy",
       [](Json& j) {
         j["search"] = {{"strategy", "annealing"}};
       },
       "search.strategy", "unknown strategy"},
      {"unknown identify",
       [](Json& j) {
         j["search"] = {{"identify", "stiffness"}};
       },
       "search.identify", "expected topology or topology_and_stiffness"},
      {"stiffness for a GA",
       [](Json& j) {
         j["search"] = {{"strategy", "hybrid"}, {"identify", "topology_and_stiffness"}};
       },
       "search.identify", "needs strategy direct"},
      {"population",
       [](Json& j) {
         j["search"] = {{"population", 1}};
       },
       "search.population", ">= 2"},
      {"mutation probability",
       [](Json& j) {
         j["search"] = {{"mutation_probability", 1.5}};
       },
       "search.mutation_probability", "[0, 1]"},
      {"negative seed",
       [](Json& j) {
         j["search"] = {{"seed", -3}};
       },
       "search.seed", ">= 0"},
  };
  for (const BadCase& c : cases) {
    Json j = ParseJson(kMinimal);
    c.mutate(j);
    std::string message;
    EXPECT_EQ(ErrorPath(j, &message), c.path) << c.what << ": " << message;
    EXPECT_NE(message.find(c.message_snippet), std::string::npos) << c.what << ": " << message;
    EXPECT_EQ(message.rfind(c.path, 0), 0u)
        << c.what << ": the message starts with the path: " << message;
  }
}

TEST(SceneCodec, MalformedJsonReportsLineAndColumn) {
  try {
    SceneFromText("{\n  \"nodes\": [[0, 0],\n  [1, 0]\n");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("line"), std::string::npos) << e.what();
  }
  // NaN is not JSON: a parse error, not a silent NaN.
  EXPECT_THROW(SceneFromText(R"({"nodes": [[NaN, 0]]})"), InputError);
}

TEST(SceneCodec, ExamplesRoundTrip) {
  for (const examples::ExampleInfo& info : examples::Catalog()) {
    const Scene s = examples::Make(info.name);
    const Json j = SceneToJson(s);
    const Scene back = SceneFromJson(ParseJson(DumpCompact(j)));
    EXPECT_EQ(SceneToJson(back), j) << info.name;
    EXPECT_EQ(back.rest, s.rest);
  }
}

TEST(SceneCodec, IdentifyRoundTripsAndIsOnlyWrittenWhenGiven) {
  Json j = ParseJson(kMinimal);
  j["search"] = {{"strategy", "direct"}, {"identify", "topology"}};
  const Scene s = SceneFromJson(j);
  ASSERT_TRUE(s.search.identify);
  EXPECT_EQ(*s.search.identify, Identify::kTopology);
  EXPECT_EQ(SceneToJson(s)["search"], j["search"]);
  j["search"].erase("identify");
  EXPECT_FALSE(SceneFromJson(j).search.identify);
  EXPECT_FALSE(SceneToJson(SceneFromJson(j))["search"].contains("identify"));
}

TEST(SceneCodec, WriterLeavesDefaultsOut) {
  const Json j = SceneToJson(SceneFromText(kMinimal));
  EXPECT_FALSE(j.contains("candidates"));
  EXPECT_FALSE(j.contains("search"));
  EXPECT_FALSE(j.contains("stiffness"));
  EXPECT_FALSE(j["reference"].contains("stiffness"));
  EXPECT_EQ(j, ParseJson(kMinimal));  // the minimal scene is its own canonical form
}

}  // namespace
}  // namespace springfit::proto

namespace springfit::proto {
namespace {

// A 2x2-cell plate with a linear FEM reference, node sets and a traction.
const char* kFemPlate = R"({
  "nodes": [[0,0],[1,0],[2,0],[0,1],[1,1],[2,1],[0,2],[1,2],[2,2]],
  "node_sets": {"bottom": [0, 1, 2], "top": [6, 7, 8]},
  "reference": {"type": "fem", "elements": [[0,1,4],[0,4,3],[1,2,5],[1,5,4],[3,4,7],[3,7,6],[4,5,8],[4,8,7]],
                "material": {"model": "linear", "young": 10.0, "poisson": 0.3}, "plane": "stress", "thickness": 0.5},
  "load_cases": [
    {"name": "pull", "fixed": "bottom", "tractions": [{"on": "top", "total": [0, 0.05]}]},
    {"name": "push", "fixed": [0, 1, 2], "forces": [{"nodes": "top", "force": [0.01, 0]}]}
  ]
})";

TEST(SceneCodec, FemReferenceNodeSetsAndTractions) {
  const Scene s = SceneFromText(kFemPlate);
  EXPECT_EQ(s.reference.kind, Reference::Kind::kFem);
  EXPECT_EQ(s.reference.fem.elements.size(), 8u);
  EXPECT_EQ(s.reference.fem.thickness, 0.5);
  EXPECT_EQ(s.load_cases[0].fixed, (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(s.load_cases[0].tractions[0].nodes, (std::vector<int>{6, 7, 8}));
  EXPECT_EQ(s.load_cases[1].forces[0].nodes, (std::vector<int>{6, 7, 8}));
  // Without "candidates", an FEM scene takes the mesh's edges and 8 nearest neighbours.
  EXPECT_EQ(s.candidates.kind, CandidateSpec::Kind::kMesh);
  EXPECT_EQ(s.candidates.k, 8);
  // Written back as read: set names stay names, the default candidates stay unwritten.
  const Json written = SceneToJson(s);
  EXPECT_EQ(written["load_cases"][0]["fixed"], "bottom");
  EXPECT_EQ(written["load_cases"][1]["forces"][0]["nodes"], "top");
  EXPECT_FALSE(written.contains("candidates"));
  EXPECT_EQ(SceneToJson(SceneFromJson(written)), written);
  // The traction is spread over the top edges: 1/4, 1/2, 1/4 of the total.
  const Problem p = Problem::Build(s);
  EXPECT_NEAR(p.load_cases()[0].force[2 * 7 + 1], 0.025, 1e-15);
  EXPECT_NEAR(p.load_cases()[0].force[2 * 6 + 1], 0.0125, 1e-15);
}

TEST(SceneCodec, FemErrorsNameThePath) {
  const std::vector<BadCase> cases = {
      {"unknown set", [](Json& j) { j["load_cases"][0]["fixed"] = "botom"; }, "load_cases[0].fixed",
       "unknown node set 'botom'"},
      {"set out of range", [](Json& j) { j["node_sets"]["top"][1] = 12; }, "node_sets.top[1]",
       "out of range"},
      {"empty set", [](Json& j) { j["node_sets"]["top"] = Json::array(); }, "node_sets.top",
       "must not be empty"},
      {"traction on a list",
       [](Json& j) {
         j["load_cases"][0]["tractions"][0]["on"] = {6, 7};
       },
       "load_cases[0].tractions[0].on", "name of a node set"},
      {"traction both",
       [](Json& j) {
         j["load_cases"][0]["tractions"][0]["per_length"] = {0, 1};
       },
       "load_cases[0].tractions[0]", "exactly one of"},
      {"traction per_area in 2D",
       [](Json& j) {
         j["load_cases"][0]["tractions"][0]["per_area"] = {0, 1};
       },
       "load_cases[0].tractions[0].per_area", "unknown field"},
      {"traction inside", [](Json& j) { j["node_sets"]["top"] = {4}; },
       "load_cases[0].tractions[0].on", "no boundary edge"},
      {"two materials", [](Json& j) { j["reference"]["materials"] = Json::array(); }, "reference",
       "exactly one of"},
      {"unknown model", [](Json& j) { j["reference"]["material"]["model"] = "mooney"; },
       "reference.material.model", "unknown material model"},
      {"poisson", [](Json& j) { j["reference"]["material"]["poisson"] = 0.5; },
       "reference.material.poisson", "(-1, 0.5)"},
      {"young", [](Json& j) { j["reference"]["material"]["young"] = 0; },
       "reference.material.young", "> 0"},
      {"plane", [](Json& j) { j["reference"]["plane"] = "shell"; }, "reference.plane",
       "stress or strain"},
      {"thickness", [](Json& j) { j["reference"]["thickness"] = -1; }, "reference.thickness",
       "> 0"},
      {"springs on fem",
       [](Json& j) {
         j["reference"]["springs"] = {{0, 1}};
       },
       "reference.springs", "only applies to type mss"},
      {"degenerate",
       [](Json& j) {
         j["reference"]["elements"][0] = {0, 1, 2};
       },
       "reference.elements[0]", "degenerate"},
      {"element size",
       [](Json& j) {
         j["reference"]["elements"][2] = {1, 2};
       },
       "reference.elements[2]", "3-node triangle"},
      {"mesh without fem",
       [](Json& j) {
         j["reference"] = {{"type", "positions"}, {"positions", Json::array()}};
         j["candidates"] = {{"type", "mesh"}};
         j["load_cases"][0].erase("tractions");
         j["load_cases"][0]["forces"] = {{{"node", 7}, {"force", {0, 1}}}};
       },
       "candidates.type", "reference of type fem"},
      {"k on radius",
       [](Json& j) {
         j["candidates"] = {{"type", "radius"}, {"radius", 1.5}, {"k", 3}};
       },
       "candidates.k", "nearest and mesh"},
  };
  for (const BadCase& c : cases) {
    Json j = ParseJson(kFemPlate);
    c.mutate(j);
    std::string message;
    EXPECT_EQ(ErrorPath(j, &message), c.path) << c.what << ": " << message;
    EXPECT_NE(message.find(c.message_snippet), std::string::npos) << c.what << ": " << message;
  }
}

}  // namespace
}  // namespace springfit::proto
