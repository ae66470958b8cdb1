// SOFA: a scene whose node holds the model's rest positions (MechanicalObject), its edges
// (EdgeSetTopologyContainer) and every spring with its stiffness and rest length
// (SpringForceField's `spring` data: "index1 index2 stiffness damping rest_length" per
// spring). Component, data and module names as in SOFA's sources for v23.06 and later
// (Sofa.Component.SolidMechanics.Spring's SpringForceField and LinearSpring); proto/MODEL.md
// says what a simulation adds (mass, solver, boundary conditions).
#include <sstream>

#include "io/model_writers.h"
#include "io/text_output.h"
#include "io/xml_text.h"

namespace springfit::io {

std::string SofaSceneText(const SpringModel& model) {
  std::ostringstream out;
  const std::string tmpl = model.dimension == 2 ? "Vec2d" : "Vec3d";
  out << "<?xml version=\"1.0\"?>\n"
      << "<!-- springfit model " << XmlCommentText(model.name) << ": "
      << XmlCommentText(model.description) << ".\n"
      << "     Static model: no damping (0 in each spring), no mass and no solver. A simulation\n"
      << "     adds them, and the boundary conditions, to the node below. -->\n"
      << "<Node name=\"root\" gravity=\"0 0" << (model.dimension == 3 ? " 0" : "") << "\">\n"
      << "  <RequiredPlugin name=\"Sofa.Component.StateContainer\"/>\n"
      << "  <RequiredPlugin name=\"Sofa.Component.Topology.Container.Dynamic\"/>\n"
      << "  <RequiredPlugin name=\"Sofa.Component.SolidMechanics.Spring\"/>\n"
      << "  <Node name=\"" << XmlEscape(model.name) << "\">\n"
      << "    <MechanicalObject name=\"dofs\" template=\"" << tmpl << "\" position=\"";
  for (int p = 0; p < model.node_count(); ++p) {
    for (int c = 0; c < model.dimension; ++c) {
      out << (p + c > 0 ? " " : "") << ExactNumber(model.rest[model.dimension * p + c]);
    }
  }
  out << "\"/>\n    <EdgeSetTopologyContainer name=\"topology\" edges=\"";
  for (std::size_t i = 0; i < model.springs.size(); ++i)
    out << (i > 0 ? " " : "") << model.springs[i].a << " " << model.springs[i].b;
  out << "\"/>\n    <SpringForceField name=\"springs\" template=\"" << tmpl << "\" spring=\"";
  for (std::size_t i = 0; i < model.springs.size(); ++i) {
    const auto& s = model.springs[i];
    out << (i > 0 ? "  " : "") << s.a << " " << s.b << " " << ExactNumber(s.stiffness) << " 0 "
        << ExactNumber(s.rest_length);
  }
  out << "\"/>\n";
  // SOFA has no per-spring flag for it: the springs the data did not determine, as a comment.
  std::string undetermined;
  for (std::size_t i = 0; i < model.springs.size(); ++i) {
    if (!model.springs[i].identified) {
      undetermined += ' ';
      undetermined += std::to_string(i);
    }
  }
  if (!undetermined.empty()) {
    out << "    <!-- springs (0-based, in the order above) whose stiffness the load cases do not "
           "determine:"
        << undetermined << " -->\n";
  }
  out << "  </Node>\n</Node>\n";
  return out.str();
}

}  // namespace springfit::io
