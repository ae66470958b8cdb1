// The per-node fields every viewer format carries beside the springs (proto/MODEL.md,
// "Validation fields"): the nodes' masses, the node sets, and per load case the reference's
// displacement, the model's own and their difference, so that a ParaView or Gmsh user sees
// where the model is off. One list, which the VTK and Gmsh writers each write in their syntax.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "io/spring_model.h"

namespace springfit::io {

struct PointField {
  std::string name;      // letters, digits, '_', '-' and '.' only (legacy VTK allows no spaces)
  int components = 1;    // 1, or 3 (2D displacements get z = 0)
  bool integer = false;  // written as integers (flags)
  std::vector<double> values;  // node-major, `components` per node
};

// node_tag (the input's node numbers, when known), mass (when known); set_NAME per node set (1 for
// a member); per load case u_reference_CASE, u_model_CASE (when the model has an equilibrium) and
// u_error_CASE = model - reference; CASE and NAME made safe by FieldName and unique.
std::vector<PointField> PointFieldsOf(const SpringModel& model);

// `text` with every character but letters, digits, '_', '-' and '.' replaced by '_'.
std::string FieldName(std::string_view text);

// VTK's cell type of the mesh's elements (5 triangle, 10 tetrahedron) and a spring's (3 line).
inline constexpr int kVtkLine = 3;
inline int VtkElementType(int dimension) {
  return dimension == 2 ? 5 : 10;
}

}  // namespace springfit::io
