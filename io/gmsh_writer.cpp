// Gmsh: the model as 2-node line elements (Gmsh type 1) of one discrete curve, through the
// Gmsh library, in MSH 4.1 ASCII; the per-spring values as element-data views appended to the
// same file. Nodes and elements are numbered from 1 (node p is tag p + 1, spring i element
// i + 1). MSH 4.1 has no field for a description: the model's (strategy, seed, E, units) goes
// in a `$Comments` section after the views, which Gmsh and meshio skip as the format allows for
// sections they do not know.
#include <gmsh.h>

#include <fstream>
#include <stdexcept>

#include "io/gmsh_session.h"
#include "io/model_writers.h"

namespace springfit::io {

void WriteGmshFile(const SpringModel& model, const std::string& path) {
  GmshSession session;
  // (A failure to write is not bad input: std::runtime_error, exit 1.)
  try {
    gmsh::model::add(model.name.empty() ? "springfit" : model.name);
    const int curve = gmsh::model::addDiscreteEntity(1);
    std::vector<std::size_t> node_tags;
    std::vector<double> coords;
    for (int p = 0; p < model.node_count(); ++p) {
      node_tags.push_back(static_cast<std::size_t>(p) + 1);
      for (int c = 0; c < 3; ++c)
        coords.push_back(c < model.dimension ? model.rest[model.dimension * p + c] : 0.0);
    }
    gmsh::model::mesh::addNodes(1, curve, node_tags, coords);
    std::vector<std::size_t> element_tags, element_nodes;
    std::vector<std::vector<double>> stiffness, rest_length, identified;
    for (std::size_t i = 0; i < model.springs.size(); ++i) {
      const auto& s = model.springs[i];
      element_tags.push_back(i + 1);
      element_nodes.push_back(static_cast<std::size_t>(s.a) + 1);
      element_nodes.push_back(static_cast<std::size_t>(s.b) + 1);
      stiffness.push_back({s.stiffness});
      rest_length.push_back({s.rest_length});
      identified.push_back({s.identified ? 1.0 : 0.0});
    }
    constexpr int kTwoNodeLine = 1;
    gmsh::model::mesh::addElementsByType(curve, kTwoNodeLine, element_tags, element_nodes);
    const int group = gmsh::model::addPhysicalGroup(1, {curve});
    gmsh::model::setPhysicalName(1, group, "springs");
    gmsh::option::setNumber("Mesh.MshFileVersion", 4.1);
    gmsh::option::setNumber("Mesh.Binary", 0);
    gmsh::option::setNumber("Mesh.SaveAll", 1);  // every node, also those no spring holds
    gmsh::write(path);
    std::string model_name;
    gmsh::model::getCurrent(model_name);
    for (const auto& [name, values] :
         {std::pair{"stiffness", &stiffness}, std::pair{"rest_length", &rest_length},
          std::pair{"identified", &identified}}) {
      const int view = gmsh::view::add(name);
      gmsh::view::addModelData(view, 0, model_name, "ElementData", element_tags, *values, 0.0, 1);
      gmsh::view::write(view, path, true);
    }
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": cannot write the model: " + e.what());
  } catch (...) {
    throw std::runtime_error(path + ": cannot write the model (Gmsh)");
  }
  // One line, whatever the scene's name holds, so that no line of it can end the section.
  std::string line = "springfit model " + model.name + ": " + model.description;
  for (char& c : line)
    if (c == '\n' || c == '\r') c = ' ';
  std::ofstream out(path, std::ios::app);
  out << "$Comments\n" << line << "\n$EndComments\n";
  if (!out.flush()) throw std::runtime_error(path + ": cannot write the model's description");
}

}  // namespace springfit::io
