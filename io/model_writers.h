// Writers of an identified model (spring_model.h) in the formats simulators and viewers load;
// the format follows the file's extension (one place: ModelFormatOfPath). Each format's
// content and limits: proto/MODEL.md.
#pragma once

#include <string>
#include <string_view>

#include "io/sofa_scene.h"
#include "io/spring_model.h"

namespace springfit::io {

enum class ModelFormat {
  kVtkLegacy,  // .vtk: legacy VTK, ASCII, an unstructured grid of line cells
  kVtu,        // .vtu: VTK XML unstructured grid, ASCII
  kGmsh,       // .msh: Gmsh 4.1 line elements, stiffness and rest length as element data
  kSofa,       // .scn: a SOFA scene of one release that runs one load case (sofa_scene.h)
  kJson,       // .json: springfit's own model format
};

// Throws InputError naming the path and the extensions known.
ModelFormat ModelFormatOfPath(const std::string& path);
std::string_view ModelFormatName(ModelFormat format);

// Writes `model` to `path` in the format of its extension (`sofa` for a .scn). Throws
// InputError for an unknown extension, std::runtime_error when the file cannot be written.
void WriteModelFile(const SpringModel& model, const std::string& path,
                    const SofaOptions& sofa = {});

// The formats' texts (the Gmsh writer goes through the Gmsh library, which writes files).
std::string VtkLegacyText(const SpringModel& model);
std::string VtuText(const SpringModel& model);
std::string ModelJsonText(const SpringModel& model);
void WriteGmshFile(const SpringModel& model, const std::string& path);

}  // namespace springfit::io
