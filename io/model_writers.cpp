#include "io/model_writers.h"

#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "engine/api/input_error.h"
#include "io/text_output.h"

namespace springfit::io {

ModelFormat ModelFormatOfPath(const std::string& path) {
  const std::string ext = LowerExtension(path);
  if (ext == ".vtk") return ModelFormat::kVtkLegacy;
  if (ext == ".vtu") return ModelFormat::kVtu;
  if (ext == ".msh") return ModelFormat::kGmsh;
  if (ext == ".scn") return ModelFormat::kSofa;
  if (ext == ".json") return ModelFormat::kJson;
  throw InputError(
      "", path + ": unknown model format '" + ext + "' (expected .vtk, .vtu, .msh, .scn or .json)");
}

std::string_view ModelFormatName(ModelFormat format) {
  switch (format) {
    case ModelFormat::kVtkLegacy:
      return "VTK legacy";
    case ModelFormat::kVtu:
      return "VTK XML unstructured grid";
    case ModelFormat::kGmsh:
      return "Gmsh MSH 4.1";
    case ModelFormat::kSofa:
      return "SOFA scene";
    case ModelFormat::kJson:
      return "springfit model JSON";
  }
  return "?";
}

void WriteModelFile(const SpringModel& model, const std::string& path, const SofaOptions& sofa) {
  const ModelFormat format = ModelFormatOfPath(path);
  if (format == ModelFormat::kGmsh) {
    WriteGmshFile(model, path);
    return;
  }
  const std::string text = format == ModelFormat::kVtkLegacy ? VtkLegacyText(model)
                           : format == ModelFormat::kVtu     ? VtuText(model)
                           : format == ModelFormat::kSofa    ? SofaSceneText(model, sofa)
                                                             : ModelJsonText(model);
  std::ofstream out(path, std::ios::binary);
  out << text;
  out.close();
  if (!out) throw std::runtime_error("cannot write " + path);
}

}  // namespace springfit::io
