#include "proto/scene_codec.h"

#include <cmath>

#include <cctype>
#include <fstream>
#include <sstream>

#include "engine/api/input_error.h"
#include "proto/fem_codec.h"
#include "proto/names.h"

namespace springfit::proto {
namespace {

NodePair ReadPair(const Json& v, const std::string& path) {
  ExpectArray(v, path);
  if (v.size() != 2)
    throw InputError(path, "expected a pair [i, j], got " + std::to_string(v.size()) + " values");
  return {ReadInt(v[0], IndexPath(path, 0)), ReadInt(v[1], IndexPath(path, 1))};
}

std::vector<int> ReadIndices(const Json& v, const std::string& path) {
  return ReadArray<int>(v, path, ReadInt);
}

// A flat d*n vector from an array of n points.
Vector ReadPoints(const Json& v, const std::string& path, int dimension) {
  ExpectArray(v, path);
  Vector out(dimension * static_cast<Eigen::Index>(v.size()));
  for (std::size_t i = 0; i < v.size(); ++i) {
    out.segment(dimension * static_cast<Eigen::Index>(i), dimension) =
        ReadVector(v[i], IndexPath(path, i), dimension);
  }
  return out;
}

void ReadNodes(const Json& v, Scene& s) {
  ExpectArray(v, "nodes");
  if (v.empty()) throw InputError("nodes", "must not be empty");
  ExpectArray(v[0], "nodes[0]");
  const int d = static_cast<int>(v[0].size());
  if (d != 2 && d != 3) {
    throw InputError("nodes[0]", "a node has 2 or 3 coordinates (the scene's dimension), got " +
                                     std::to_string(d));
  }
  s.dimension = d;
  s.rest = ReadPoints(v, "nodes", d);
}

void ReadCandidates(const Json& v, Scene& s) {
  const std::string path = "candidates";
  ExpectKeys(v, path, {"type", "spacing", "k", "radius", "pairs"});
  if (!v.contains("type")) throw InputError(JoinPath(path, "type"), "required");
  const std::string type = ReadString(v["type"], JoinPath(path, "type"));
  const auto kind = ParseCandidateKind(type);
  if (!kind) {
    throw InputError(
        JoinPath(path, "type"),
        "unknown candidate type '" + type + "' (expected grid, nearest, radius, pairs or mesh)");
  }
  s.candidates.kind = *kind;
  auto only_for = [&](const char* key, CandidateSpec::Kind k) {
    if (v.contains(key) && *kind != k) {
      throw InputError(JoinPath(path, key),
                       "only applies to type " + std::string(CandidateKindName(k)));
    }
  };
  only_for("spacing", CandidateSpec::Kind::kGrid);
  if (v.contains("k") && *kind != CandidateSpec::Kind::kNearest &&
      *kind != CandidateSpec::Kind::kMesh) {
    throw InputError(JoinPath(path, "k"), "only applies to types nearest and mesh");
  }
  if (*kind == CandidateSpec::Kind::kMesh) s.candidates.k = 0;
  only_for("radius", CandidateSpec::Kind::kRadius);
  only_for("pairs", CandidateSpec::Kind::kPairs);
  if (v.contains("spacing")) {
    const std::string p = JoinPath(path, "spacing");
    if (v["spacing"].is_number()) {
      s.candidates.spacing.assign(s.dimension, ReadNumber(v["spacing"], p));
    } else {
      const Vector h = ReadVector(v["spacing"], p, s.dimension);
      s.candidates.spacing.assign(h.data(), h.data() + h.size());
    }
  }
  if (v.contains("k")) s.candidates.k = ReadInt(v["k"], JoinPath(path, "k"));
  if (*kind == CandidateSpec::Kind::kRadius) {
    if (!v.contains("radius"))
      throw InputError(JoinPath(path, "radius"), "required for type radius");
    s.candidates.radius = ReadNumber(v["radius"], JoinPath(path, "radius"));
  }
  if (*kind == CandidateSpec::Kind::kPairs) {
    if (!v.contains("pairs")) throw InputError(JoinPath(path, "pairs"), "required for type pairs");
    s.candidates.pairs = ReadNodePairs(v["pairs"], JoinPath(path, "pairs"));
  }
}

void ReadReference(const Json& v, Scene& s) {
  const std::string path = "reference";
  ExpectKeys(v, path,
             {"type", "springs", "stiffness", "positions", "elements", "material", "materials",
              "element_materials", "element_tags", "plane", "thickness"});
  if (!v.contains("type")) throw InputError(JoinPath(path, "type"), "required");
  const std::string type = ReadString(v["type"], JoinPath(path, "type"));
  const auto kind = ParseReferenceKind(type);
  if (!kind) {
    throw InputError(JoinPath(path, "type"),
                     "unknown reference type '" + type + "' (expected mss, positions or fem)");
  }
  Reference& r = s.reference;
  r.kind = *kind;
  // Each field belongs to one type.
  const std::pair<const char*, Reference::Kind> owners[] = {
      {"springs", Reference::Kind::kMss},           {"stiffness", Reference::Kind::kMss},
      {"positions", Reference::Kind::kPositions},   {"elements", Reference::Kind::kFem},
      {"material", Reference::Kind::kFem},          {"materials", Reference::Kind::kFem},
      {"element_materials", Reference::Kind::kFem}, {"plane", Reference::Kind::kFem},
      {"thickness", Reference::Kind::kFem},         {"element_tags", Reference::Kind::kFem}};
  for (const auto& [key, owner] : owners) {
    if (v.contains(key) && owner != r.kind) {
      throw InputError(JoinPath(path, key),
                       "only applies to type " + std::string(ReferenceKindName(owner)));
    }
  }
  if (r.kind == Reference::Kind::kFem) {
    ReadFemReference(v, s.dimension, r.fem);
    return;
  }
  if (r.kind == Reference::Kind::kMss) {
    if (!v.contains("springs"))
      throw InputError(JoinPath(path, "springs"), "required for type mss");
    r.springs = ReadNodePairs(v["springs"], JoinPath(path, "springs"));
    r.stiffness = {1.0};
    if (v.contains("stiffness")) {
      const std::string p = JoinPath(path, "stiffness");
      if (v["stiffness"].is_array()) {
        const Json& a = v["stiffness"];
        r.stiffness.clear();
        for (std::size_t m = 0; m < a.size(); ++m)
          r.stiffness.push_back(ReadNumber(a[m], IndexPath(p, m)));
      } else {
        r.stiffness = {ReadNumber(v["stiffness"], p)};
      }
    }
    return;
  }
  if (!v.contains("positions"))
    throw InputError(JoinPath(path, "positions"), "required for type positions");
  const std::string p = JoinPath(path, "positions");
  ExpectArray(v["positions"], p);
  for (std::size_t k = 0; k < v["positions"].size(); ++k) {
    r.positions.push_back(ReadPoints(v["positions"][k], IndexPath(p, k), s.dimension));
  }
}

void ReadNodeSets(const Json& v, Scene& s) {
  ExpectObject(v, "node_sets");
  for (const auto& [name, nodes] : v.items()) {
    const std::string p = JoinPath("node_sets", name);
    if (name.empty()) throw InputError("node_sets", "a node set needs a non-empty name");
    std::vector<int> list = ReadIndices(nodes, p);
    if (list.empty()) throw InputError(p, "must not be empty");
    s.node_sets[name] = std::move(list);
  }
}

// A list of node indices, or a string naming one of the scene's node sets (its name is
// returned in `set`).
std::vector<int> ReadNodeList(const Json& v, const std::string& path, const Scene& s,
                              std::string& set) {
  if (!v.is_string()) return ReadIndices(v, path);
  set = v.get<std::string>();
  auto it = s.node_sets.find(set);
  if (it == s.node_sets.end()) {
    // As in a CalculiX deck, whose set names are case-insensitive: `left` names a mesh's
    // `Left` when no other set differs from it by case alone.
    const auto lower = [](std::string text) {
      for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      return text;
    };
    std::vector<decltype(it)> matches;
    for (auto m = s.node_sets.begin(); m != s.node_sets.end(); ++m)
      if (lower(m->first) == lower(set)) matches.push_back(m);
    if (matches.size() > 1)
      throw InputError(path, "node set '" + set + "' matches " + matches[0]->first + " and " +
                                 matches[1]->first +
                                 " but by case alone: write the name as the scene spells it");
    if (matches.size() == 1) {
      set = matches[0]->first;
      return matches[0]->second;
    }
  }
  if (it == s.node_sets.end()) {
    std::string known;
    for (const auto& [name, nodes] : s.node_sets) known += (known.empty() ? "" : ", ") + name;
    throw InputError(path, "unknown node set '" + set + "' (" +
                               (known.empty() ? std::string("the scene has no node_sets")
                                              : "the scene's node_sets: " + known) +
                               ")");
  }
  return it->second;
}

std::vector<Traction> ReadTractions(const Json& v, const std::string& path, const Scene& s) {
  ExpectArray(v, path);
  std::vector<Traction> out;
  const char* density_key = s.dimension == 2 ? "per_length" : "per_area";
  for (std::size_t m = 0; m < v.size(); ++m) {
    const std::string p = IndexPath(path, m);
    ExpectKeys(v[m], p, {"on", "total", density_key});
    Traction t;
    const Json& on = RequiredMember(v[m], p, "on");
    if (!on.is_string()) throw InputError(JoinPath(p, "on"), "expected the name of a node set");
    t.nodes = ReadNodeList(on, JoinPath(p, "on"), s, t.on);
    if (v[m].contains("total") == v[m].contains(density_key)) {
      throw InputError(p, std::string("needs exactly one of \"total\" or \"") + density_key + "\"");
    }
    t.total = v[m].contains("total");
    const char* key = t.total ? "total" : density_key;
    t.value = ReadVector(v[m][key], JoinPath(p, key), s.dimension);
    out.push_back(std::move(t));
  }
  return out;
}

std::vector<NodalLoad> ReadLoads(const Json& v, const std::string& path, const char* value_key,
                                 const Scene& s) {
  const int d = s.dimension;
  ExpectArray(v, path);
  std::vector<NodalLoad> loads;
  for (std::size_t m = 0; m < v.size(); ++m) {
    const std::string p = IndexPath(path, m);
    ExpectKeys(v[m], p, {"node", "nodes", value_key});
    NodalLoad load;
    if (v[m].contains("node") == v[m].contains("nodes")) {
      throw InputError(p, "needs exactly one of \"node\" or \"nodes\"");
    }
    if (v[m].contains("node")) {
      load.single = true;
      load.nodes = {ReadInt(v[m]["node"], JoinPath(p, "node"))};
    } else {
      load.nodes = ReadNodeList(v[m]["nodes"], JoinPath(p, "nodes"), s, load.set);
    }
    if (!v[m].contains(value_key)) throw InputError(JoinPath(p, value_key), "required");
    load.value = ReadVector(v[m][value_key], JoinPath(p, value_key), d);
    loads.push_back(std::move(load));
  }
  return loads;
}

void ReadLoadCases(const Json& v, Scene& s) {
  ExpectArray(v, "load_cases");
  for (std::size_t k = 0; k < v.size(); ++k) {
    const std::string p = IndexPath("load_cases", k);
    ExpectKeys(v[k], p, {"name", "fixed", "forces", "displacements", "tractions"});
    LoadCase lc;
    if (v[k].contains("name")) lc.name = ReadString(v[k]["name"], JoinPath(p, "name"));
    if (v[k].contains("fixed"))
      lc.fixed = ReadNodeList(v[k]["fixed"], JoinPath(p, "fixed"), s, lc.fixed_set);
    if (v[k].contains("forces"))
      lc.forces = ReadLoads(v[k]["forces"], JoinPath(p, "forces"), "force", s);
    if (v[k].contains("displacements")) {
      lc.displacements =
          ReadLoads(v[k]["displacements"], JoinPath(p, "displacements"), "displacement", s);
    }
    if (v[k].contains("tractions"))
      lc.tractions = ReadTractions(v[k]["tractions"], JoinPath(p, "tractions"), s);
    s.load_cases.push_back(std::move(lc));
  }
}

void ReadSearch(const Json& v, SearchSettings& st) {
  const std::string path = "search";
  ExpectKeys(v, path,
             {"strategy", "identify", "response", "seed", "population", "crossover_probability",
              "mutation_probability", "max_generations", "target_normalized_error", "max_seconds",
              "stall_generations", "max_springs", "target_error", "regularization", "probes",
              "max_spread", "load_size"});
  if (v.contains("strategy")) {
    st.strategy = StrategyFromName(ReadString(v["strategy"], JoinPath(path, "strategy")),
                                   JoinPath(path, "strategy"));
  }
  if (v.contains("identify")) {
    st.identify = IdentifyFromName(ReadString(v["identify"], JoinPath(path, "identify")),
                                   JoinPath(path, "identify"));
  }
  if (v.contains("response")) {
    st.response = ResponseFromName(ReadString(v["response"], JoinPath(path, "response")),
                                   JoinPath(path, "response"));
  }
  if (v.contains("seed")) st.seed = ReadUint64(v["seed"], JoinPath(path, "seed"));
  if (v.contains("population"))
    st.population = ReadInt(v["population"], JoinPath(path, "population"));
  if (v.contains("crossover_probability")) {
    st.crossover_probability =
        ReadNumber(v["crossover_probability"], JoinPath(path, "crossover_probability"));
  }
  if (v.contains("mutation_probability")) {
    st.mutation_probability =
        ReadNumber(v["mutation_probability"], JoinPath(path, "mutation_probability"));
  }
  if (v.contains("max_generations"))
    st.max_generations = ReadInt(v["max_generations"], JoinPath(path, "max_generations"));
  if (v.contains("max_seconds"))
    st.max_seconds = ReadNumber(v["max_seconds"], JoinPath(path, "max_seconds"));
  if (v.contains("stall_generations")) {
    st.stall_generations = ReadInt(v["stall_generations"], JoinPath(path, "stall_generations"));
  }
  if (v.contains("max_springs"))
    st.max_springs = ReadInt(v["max_springs"], JoinPath(path, "max_springs"));
  if (v.contains("target_error"))
    st.target_error = ReadNumber(v["target_error"], JoinPath(path, "target_error"));
  if (v.contains("max_spread"))
    st.max_spread = ReadNumber(v["max_spread"], JoinPath(path, "max_spread"));
  if (v.contains("load_size"))
    st.load_size = ReadNumber(v["load_size"], JoinPath(path, "load_size"));
  if (v.contains("regularization")) {
    const Json& r = v["regularization"];
    const std::string where = JoinPath(path, "regularization");
    if (r.is_string()) {
      st.regularization = RegularizationFromText(r.get<std::string>(), where);
    } else {
      st.regularization = SearchSettings::Regularization{false, ReadNumber(r, where)};
      if (!(st.regularization->strength >= 0.0))
        throw InputError(where, "must be \"auto\" or a finite number >= 0");
    }
  }
  if (v.contains("probes")) {
    const Json& r = v["probes"];
    const std::string where = JoinPath(path, "probes");
    if (r.is_string()) {
      st.probes = ProbesFromText(r.get<std::string>(), where);
    } else {
      const int count = ReadInt(r, where);
      if (count < 1 || count > SearchOptions::kMaxProbes)
        throw InputError(where, "must be \"auto\", \"none\" or a count from 1 to " +
                                    std::to_string(SearchOptions::kMaxProbes));
      st.probes = count;
    }
  }
  if (v.contains("target_normalized_error")) {
    st.target_normalized_error =
        ReadNumber(v["target_normalized_error"], JoinPath(path, "target_normalized_error"));
  }
}

Json VectorToJson(const Vector& v) {
  Json a = Json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(v[i]);
  return a;
}

Json LoadsToJson(const std::vector<NodalLoad>& loads, const char* value_key) {
  Json a = Json::array();
  for (const NodalLoad& l : loads) {
    Json o;
    if (!l.set.empty()) {
      o["nodes"] = l.set;
    } else if (l.single && l.nodes.size() == 1) {
      o["node"] = l.nodes[0];
    } else {
      o["nodes"] = l.nodes;
    }
    o[value_key] = VectorToJson(l.value);
    a.push_back(std::move(o));
  }
  return a;
}

}  // namespace

Json LoadCaseToJson(const LoadCase& lc, int dimension) {
  Json o = Json::object();
  if (!lc.name.empty()) o["name"] = lc.name;
  if (!lc.fixed_set.empty()) {
    o["fixed"] = lc.fixed_set;
  } else if (!lc.fixed.empty()) {
    o["fixed"] = lc.fixed;
  }
  if (!lc.forces.empty()) o["forces"] = LoadsToJson(lc.forces, "force");
  if (!lc.displacements.empty()) o["displacements"] = LoadsToJson(lc.displacements, "displacement");
  if (!lc.tractions.empty()) {
    Json tractions = Json::array();
    for (const Traction& t : lc.tractions) {
      Json tj;
      tj["on"] = t.on;
      tj[t.total ? "total" : (dimension == 2 ? "per_length" : "per_area")] = VectorToJson(t.value);
      tractions.push_back(std::move(tj));
    }
    o["tractions"] = std::move(tractions);
  }
  return o;
}

Json PointsToJson(const Vector& flat, int d) {
  Json a = Json::array();
  for (Eigen::Index i = 0; i < flat.size() / d; ++i) {
    Json p = Json::array();
    for (int c = 0; c < d; ++c) p.push_back(flat[d * i + c]);
    a.push_back(std::move(p));
  }
  return a;
}

CandidateSpec FemDefaultCandidates() {
  CandidateSpec c;
  c.kind = CandidateSpec::Kind::kMesh;
  c.k = 8;
  return c;
}

std::vector<NodePair> ReadNodePairs(const Json& v, const std::string& path) {
  return ReadArray<NodePair>(v, path, ReadPair);
}

Json PairsToJson(const std::vector<NodePair>& pairs) {
  Json a = Json::array();
  for (const NodePair& p : pairs) a.push_back({p.first, p.second});
  return a;
}

Scene SceneFromJson(const Json& json) {
  ExpectKeys(json, "",
             {"name", "description", "nodes", "node_tags", "candidates", "node_sets", "reference",
              "load_cases", "stiffness", "search", "units"});
  Scene s;
  if (json.contains("name")) s.name = ReadString(json["name"], "name");
  if (json.contains("description")) s.description = ReadString(json["description"], "description");
  for (const char* key : {"nodes", "reference", "load_cases"}) {
    if (!json.contains(key)) throw InputError(key, "required");
  }
  ReadNodes(json["nodes"], s);
  if (json.contains("node_tags")) {
    s.node_tags = ReadTags(json["node_tags"], "node_tags",
                           static_cast<std::size_t>(s.rest.size() / s.dimension), "nodes");
  }
  if (json.contains("candidates")) ReadCandidates(json["candidates"], s);
  if (json.contains("node_sets")) ReadNodeSets(json["node_sets"], s);
  ReadLoadCases(json["load_cases"], s);
  ReadReference(json["reference"], s);
  if (!json.contains("candidates") && s.reference.kind == Reference::Kind::kFem)
    s.candidates = FemDefaultCandidates();
  if (json.contains("stiffness")) s.training_stiffness = ReadNumber(json["stiffness"], "stiffness");
  if (json.contains("search")) ReadSearch(json["search"], s.search);
  if (json.contains("units")) {
    const Json& u = json["units"];
    ExpectObject(u, "units");
    ExpectKeys(u, "units", {"length", "force", "modulus"});
    Scene::Units units;
    units.length = ReadString(RequiredMember(u, "units", "length"), "units.length");
    units.force = ReadString(RequiredMember(u, "units", "force"), "units.force");
    if (u.contains("modulus")) units.modulus = ReadString(u["modulus"], "units.modulus");
    s.units = units;
  }
  return s;
}

Scene SceneFromText(std::string_view text) {
  return SceneFromJson(ParseJson(text));
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError("", "cannot open '" + path + "'");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

Scene LoadSceneFile(const std::string& path) {
  return SceneFromText(ReadFile(path));
}

Json SearchSettingsToJson(const SearchSettings& st) {
  const SearchSettings d;
  Json sj = Json::object();
  if (st.strategy != d.strategy) sj["strategy"] = StrategyName(st.strategy);
  if (st.identify) sj["identify"] = IdentifyName(*st.identify);
  if (st.response) sj["response"] = ResponseName(*st.response);
  if (st.seed != d.seed) sj["seed"] = st.seed;
  if (st.population) sj["population"] = *st.population;
  if (st.crossover_probability) sj["crossover_probability"] = *st.crossover_probability;
  if (st.mutation_probability) sj["mutation_probability"] = *st.mutation_probability;
  if (st.max_generations != d.max_generations) sj["max_generations"] = st.max_generations;
  if (st.max_seconds) sj["max_seconds"] = *st.max_seconds;
  if (st.stall_generations) sj["stall_generations"] = *st.stall_generations;
  if (st.max_springs) sj["max_springs"] = *st.max_springs;
  if (st.target_error) sj["target_error"] = *st.target_error;
  if (st.max_spread) sj["max_spread"] = *st.max_spread;
  if (st.load_size) sj["load_size"] = *st.load_size;
  if (st.regularization) {
    sj["regularization"] =
        st.regularization->automatic ? Json("auto") : Json(st.regularization->strength);
  }
  if (st.probes) sj["probes"] = ProbesToJson(*st.probes);
  if (st.target_normalized_error != d.target_normalized_error)
    sj["target_normalized_error"] = st.target_normalized_error;
  return sj;
}

SearchSettings SearchSettingsFromJson(const Json& json) {
  SearchSettings settings;
  ReadSearch(json, settings);
  return settings;
}

namespace {

// The scene's candidate rule, or null when it is the default for its reference (left out).
Json CandidatesToJson(const Scene& s) {
  const CandidateSpec& c = s.candidates;
  const bool default_candidates =
      s.reference.kind == Reference::Kind::kFem
          ? c.kind == FemDefaultCandidates().kind && c.k == FemDefaultCandidates().k
          : c.kind == CandidateSpec::Kind::kGrid && c.spacing.empty();
  if (default_candidates) return nullptr;
  Json cj;
  cj["type"] = CandidateKindName(c.kind);
  switch (c.kind) {
    case CandidateSpec::Kind::kGrid:
      if (c.spacing.empty())
        break;  // inferred (written out because an FEM scene's default differs)
      if (std::all_of(c.spacing.begin(), c.spacing.end(),
                      [&](double h) { return h == c.spacing[0]; })) {
        cj["spacing"] = c.spacing[0];
      } else {
        cj["spacing"] = c.spacing;
      }
      break;
    case CandidateSpec::Kind::kNearest:
      cj["k"] = c.k;
      break;
    case CandidateSpec::Kind::kRadius:
      cj["radius"] = c.radius;
      break;
    case CandidateSpec::Kind::kPairs:
      cj["pairs"] = PairsToJson(c.pairs);
      break;
    case CandidateSpec::Kind::kMesh:
      if (c.k > 0) cj["k"] = c.k;
      break;
  }
  return cj;
}

// The reference: an MSS's springs and stiffness, an FEM's mesh and materials, or positions.
Json ReferenceToJson(const Scene& s) {
  Json r;
  r["type"] = ReferenceKindName(s.reference.kind);
  if (s.reference.kind == Reference::Kind::kMss) {
    r["springs"] = PairsToJson(s.reference.springs);
    if (s.reference.stiffness.size() == 1) {
      if (s.reference.stiffness[0] != 1.0) r["stiffness"] = s.reference.stiffness[0];
    } else {
      r["stiffness"] = s.reference.stiffness;
    }
  } else if (s.reference.kind == Reference::Kind::kFem) {
    WriteFemReference(s.reference.fem, r);
  } else {
    Json positions = Json::array();
    for (const Vector& p : s.reference.positions) positions.push_back(PointsToJson(p, s.dimension));
    r["positions"] = std::move(positions);
  }
  return r;
}

}  // namespace

Json UnitsToJson(const DerivedUnits& u) {
  return {{"length", u.length},   {"force", u.force}, {"stiffness", u.stiffness},
          {"modulus", u.modulus}, {"mass", u.mass},   {"time", u.time}};
}

std::string UnitsText(const Json& units) {
  if (!units.is_object()) return "";
  const auto field = [&](const char* name) -> std::string {
    const auto it = units.find(name);
    return it != units.end() && it->is_string() ? it->get_ref<const std::string&>() : "?";
  };
  return "length " + field("length") + ", force " + field("force") + ", stiffness " +
         field("stiffness") + ", mass " + field("mass") + ", time " + field("time") +
         " (E is relative: no unit)";
}

Json SceneToJson(const Scene& s) {
  Json j;
  if (!s.name.empty()) j["name"] = s.name;
  if (!s.description.empty()) j["description"] = s.description;
  j["nodes"] = PointsToJson(s.rest, s.dimension);

  Json candidates = CandidatesToJson(s);
  if (!candidates.is_null()) j["candidates"] = std::move(candidates);

  if (!s.node_tags.empty()) j["node_tags"] = s.node_tags;
  if (!s.node_sets.empty()) {
    Json sets = Json::object();
    for (const auto& [name, nodes] : s.node_sets) sets[name] = nodes;
    j["node_sets"] = std::move(sets);
  }

  j["reference"] = ReferenceToJson(s);

  Json cases = Json::array();
  for (const LoadCase& lc : s.load_cases) cases.push_back(LoadCaseToJson(lc, s.dimension));
  j["load_cases"] = std::move(cases);
  if (s.training_stiffness) j["stiffness"] = *s.training_stiffness;

  Json sj = SearchSettingsToJson(s.search);
  if (!sj.empty()) j["search"] = std::move(sj);
  if (s.units) {
    Json u;
    u["length"] = s.units->length;
    u["force"] = s.units->force;
    if (!s.units->modulus.empty()) u["modulus"] = s.units->modulus;
    j["units"] = std::move(u);
  }
  return j;
}

}  // namespace springfit::proto
