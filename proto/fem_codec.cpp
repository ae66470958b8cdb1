#include "proto/fem_codec.h"

#include "engine/api/input_error.h"
#include "proto/names.h"

namespace springfit::proto {
namespace {

Material ReadMaterial(const Json& v, const std::string& path) {
  ExpectKeys(v, path, {"model", "young", "poisson", "density"});
  Material m;
  const std::string model = ReadString(RequiredMember(v, path, "model"), JoinPath(path, "model"));
  const auto parsed = ParseMaterialModel(model);
  if (!parsed) {
    throw InputError(JoinPath(path, "model"),
                     "unknown material model '" + model +
                         "' (expected linear, st_venant_kirchhoff or neo_hookean)");
  }
  m.model = *parsed;
  m.young = ReadNumber(RequiredMember(v, path, "young"), JoinPath(path, "young"));
  m.poisson = ReadNumber(RequiredMember(v, path, "poisson"), JoinPath(path, "poisson"));
  if (v.contains("density")) m.density = ReadNumber(v["density"], JoinPath(path, "density"));
  return m;
}

Json MaterialToJson(const Material& m) {
  Json j;
  j["model"] = MaterialModelName(m.model);
  j["young"] = m.young;
  j["poisson"] = m.poisson;
  if (m.density) j["density"] = *m.density;
  return j;
}

}  // namespace

void ReadFemReference(const Json& v, int dimension, FemReference& fem) {
  const std::string path = "reference";
  const std::string ep = JoinPath(path, "elements");
  ExpectArray(RequiredMember(v, path, "elements"), ep);
  const Json& elements = v["elements"];
  fem.elements.reserve(elements.size());
  for (std::size_t e = 0; e < elements.size(); ++e) {
    const std::string p = IndexPath(ep, e);
    ExpectArray(elements[e], p);
    std::vector<int> nodes;
    nodes.reserve(elements[e].size());
    for (std::size_t a = 0; a < elements[e].size(); ++a)
      nodes.push_back(ReadInt(elements[e][a], IndexPath(p, a)));
    fem.elements.push_back(std::move(nodes));
  }
  if (v.contains("element_tags")) {
    fem.element_tags = ReadTags(v["element_tags"], JoinPath(path, "element_tags"),
                                fem.elements.size(), "elements");
  }
  if (v.contains("material") == v.contains("materials")) {
    throw InputError(path,
                     "an fem reference needs exactly one of \"material\" or \"materials\" (with "
                     "\"element_materials\")");
  }
  if (v.contains("material")) {
    if (v.contains("element_materials")) {
      throw InputError(JoinPath(path, "element_materials"), "only applies with \"materials\"");
    }
    fem.materials = {ReadMaterial(v["material"], JoinPath(path, "material"))};
  } else {
    fem.regions = true;
    const std::string mp = JoinPath(path, "materials");
    ExpectArray(v["materials"], mp);
    if (v["materials"].empty()) throw InputError(mp, "must not be empty");
    for (std::size_t m = 0; m < v["materials"].size(); ++m) {
      fem.materials.push_back(ReadMaterial(v["materials"][m], IndexPath(mp, m)));
    }
    const std::string ip = JoinPath(path, "element_materials");
    ExpectArray(RequiredMember(v, path, "element_materials"), ip);
    for (std::size_t e = 0; e < v["element_materials"].size(); ++e) {
      fem.element_material.push_back(ReadInt(v["element_materials"][e], IndexPath(ip, e)));
    }
  }
  if (v.contains("plane")) {
    const std::string pp = JoinPath(path, "plane");
    if (dimension != 2) throw InputError(pp, "only applies to 2D scenes");
    const std::string plane = ReadString(v["plane"], pp);
    const auto mode = ParsePlaneMode(plane);
    if (!mode) throw InputError(pp, "unknown value '" + plane + "' (expected stress or strain)");
    fem.plane = *mode;
    fem.plane_given = true;
  }
  if (v.contains("thickness")) {
    const std::string tp = JoinPath(path, "thickness");
    if (dimension != 2) throw InputError(tp, "only applies to 2D scenes");
    fem.thickness = ReadNumber(v["thickness"], tp);
    fem.thickness_given = true;
  }
}

void WriteFemReference(const FemReference& fem, Json& r) {
  Json elements = Json::array();
  for (const std::vector<int>& e : fem.elements) elements.push_back(e);
  r["elements"] = std::move(elements);
  if (fem.regions) {
    Json materials = Json::array();
    for (const Material& m : fem.materials) materials.push_back(MaterialToJson(m));
    r["materials"] = std::move(materials);
    r["element_materials"] = fem.element_material;
  } else {
    r["material"] = MaterialToJson(fem.materials[0]);
  }
  if (!fem.element_tags.empty()) r["element_tags"] = fem.element_tags;
  if (fem.plane_given) r["plane"] = PlaneModeName(fem.plane);
  if (fem.thickness_given) r["thickness"] = fem.thickness;
}

}  // namespace springfit::proto
