// Gmsh: the model as 2-node line elements (Gmsh type 1) of one discrete curve, through the
// Gmsh library, in MSH 4.1 ASCII; the per-spring values as element-data views appended to the
// same file. Nodes and elements are numbered from 1 (node p is tag p + 1, spring i element
// i + 1). MSH 4.1 has no field for a description: the model's (strategy, seed, E, units) goes
// in a `$Comments` section after the views, which Gmsh and meshio skip as the format allows for
// sections they do not know.
#include <gmsh.h>

#include <fstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "io/gmsh_session.h"
#include "io/model_fields.h"
#include "io/model_writers.h"

namespace springfit::io {

namespace {

// The element-data views' values, one row per element (springs, then the mesh's elements).
struct ElementData {
  std::vector<std::size_t> tags;
  std::vector<std::vector<double>> stiffness, rest_length, identified, dead, cell_kind;
};

// Every node, on one discrete curve: returns their tags.
std::vector<std::size_t> AddNodeTags(const SpringModel& model, int curve) {
  std::vector<std::size_t> node_tags;
  std::vector<double> coords;
  for (int p = 0; p < model.node_count(); ++p) {
    node_tags.push_back(static_cast<std::size_t>(p) + 1);
    for (int c = 0; c < 3; ++c)
      coords.push_back(c < model.dimension ? model.rest[model.dimension * p + c] : 0.0);
  }
  gmsh::model::mesh::addNodes(1, curve, node_tags, coords);
  return node_tags;
}

// The springs as 2-node lines on the curve, in the physical group `springs`.
ElementData AddSpringLines(const SpringModel& model, int curve) {
  ElementData data;
  std::vector<std::size_t> element_nodes;
  for (std::size_t i = 0; i < model.springs.size(); ++i) {
    const auto& s = model.springs[i];
    data.tags.push_back(i + 1);
    element_nodes.push_back(static_cast<std::size_t>(s.a) + 1);
    element_nodes.push_back(static_cast<std::size_t>(s.b) + 1);
    data.stiffness.push_back({s.stiffness});
    data.rest_length.push_back({s.rest_length});
    data.identified.push_back({static_cast<double>(s.identified)});
    data.dead.push_back({s.dead ? 1.0 : 0.0});
    data.cell_kind.push_back({0.0});
  }
  constexpr int kTwoNodeLine = 1;
  gmsh::model::mesh::addElementsByType(curve, kTwoNodeLine, data.tags, element_nodes);
  const int group = gmsh::model::addPhysicalGroup(1, {curve});
  gmsh::model::setPhysicalName(1, group, "springs");
  return data;
}

// The FEM mesh (triangles, Gmsh type 2; tetrahedra, type 4) as its own entity and physical
// group `mesh`, elements numbered after the springs. The spring data is 0 on the mesh's
// elements, cell_kind 1 (as in the VTK files): every element is in the views.
void AddMeshElements(const SpringModel& model, ElementData& data) {
  if (model.elements.empty()) return;
  const int body = gmsh::model::addDiscreteEntity(model.dimension);
  std::vector<std::size_t> tags, nodes;
  for (std::size_t e = 0; e < model.elements.size(); ++e) {
    tags.push_back(model.springs.size() + e + 1);
    for (int v : model.elements[e]) nodes.push_back(static_cast<std::size_t>(v) + 1);
  }
  gmsh::model::mesh::addElementsByType(body, model.dimension == 2 ? 2 : 4, tags, nodes);
  data.tags.insert(data.tags.end(), tags.begin(), tags.end());
  for (auto* values : {&data.stiffness, &data.rest_length, &data.identified, &data.dead})
    values->resize(data.tags.size(), {0.0});
  data.cell_kind.resize(data.tags.size(), {1.0});
  const int mesh = gmsh::model::addPhysicalGroup(model.dimension, {body});
  gmsh::model::setPhysicalName(model.dimension, mesh, "mesh");
}

// The per-element values, then the validation fields (one node-data view each), appended.
void WriteViews(const SpringModel& model, const ElementData& data,
                const std::vector<std::size_t>& node_tags, const std::string& path) {
  std::string model_name;
  gmsh::model::getCurrent(model_name);
  for (const auto& [name, values] :
       {std::pair{"stiffness", &data.stiffness}, std::pair{"rest_length", &data.rest_length},
        std::pair{"identified", &data.identified}, std::pair{"dead", &data.dead},
        std::pair{"cell_kind", &data.cell_kind}}) {
    const int view = gmsh::view::add(name);
    gmsh::view::addModelData(view, 0, model_name, "ElementData", data.tags, *values, 0.0, 1);
    gmsh::view::write(view, path, true);
  }
  for (const PointField& f : PointFieldsOf(model)) {
    const int view = gmsh::view::add(f.name);
    std::vector<std::vector<double>> values;
    for (int p = 0; p < model.node_count(); ++p)
      values.emplace_back(f.values.begin() + f.components * p,
                          f.values.begin() + f.components * (p + 1));
    gmsh::view::addModelData(view, 0, model_name, "NodeData", node_tags, values, 0.0, f.components);
    gmsh::view::write(view, path, true);
  }
}

// The description in a `$Comments` section: one line, whatever the scene's name holds, so that
// no line of it can end the section.
void AppendDescription(const SpringModel& model, const std::string& path) {
  std::string line = "springfit model " + model.name + ": " + model.description;
  for (char& c : line)
    if (c == '\n' || c == '\r') c = ' ';
  std::ofstream out(path, std::ios::app);
  out << "$Comments\n" << line << "\n$EndComments\n";
  if (!out.flush()) throw std::runtime_error(path + ": cannot write the model's description");
}

}  // namespace

void WriteGmshFile(const SpringModel& model, const std::string& path) {
  GmshSession session;
  // (A failure to write is not bad input: std::runtime_error, exit 1.)
  try {
    gmsh::model::add(model.name.empty() ? "springfit" : model.name);
    const int curve = gmsh::model::addDiscreteEntity(1);
    const std::vector<std::size_t> node_tags = AddNodeTags(model, curve);
    ElementData data = AddSpringLines(model, curve);
    AddMeshElements(model, data);
    gmsh::option::setNumber("Mesh.MshFileVersion", 4.1);
    gmsh::option::setNumber("Mesh.Binary", 0);
    gmsh::option::setNumber("Mesh.SaveAll", 1);  // every node, also those no spring holds
    // The mesh once, then the views alone: by default Gmsh writes the mesh again before each
    // appended view (13 copies of every node and element, which Gmsh's reader then merged
    // into duplicate nodes).
    gmsh::option::setNumber("PostProcessing.SaveMesh", 0);
    gmsh::write(path);
    WriteViews(model, data, node_tags, path);
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": cannot write the model: " + e.what());
  } catch (...) {
    throw std::runtime_error(path + ": cannot write the model (Gmsh)");
  }
  AppendDescription(model, path);
}

}  // namespace springfit::io
