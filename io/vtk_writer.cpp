// VTK: the model as an unstructured grid of line cells (VTK_LINE = 3), points in 3D (z = 0 for
// a 2D model), per-cell stiffness, rest length and whether the data determined the stiffness.
#include <sstream>

#include "io/model_writers.h"
#include "io/text_output.h"
#include "io/xml_text.h"

namespace springfit::io {
namespace {

constexpr int kVtkLine = 3;

// Point p's three coordinates.
std::string PointText(const SpringModel& model, int p) {
  std::string s;
  for (int c = 0; c < 3; ++c) {
    if (c > 0) s += ' ';
    s += c < model.dimension ? ExactNumber(model.rest[model.dimension * p + c]) : "0";
  }
  return s;
}

}  // namespace

std::string VtkLegacyText(const SpringModel& model) {
  std::ostringstream out;
  // The title line: one line of at most 256 characters.
  std::string title = "springfit model " + model.name + ": " + model.description;
  for (char& c : title) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  if (title.size() > 255) title.resize(255);
  const std::size_t m = model.springs.size();
  out << "# vtk DataFile Version 3.0\n" << title << "\nASCII\nDATASET UNSTRUCTURED_GRID\n";
  out << "POINTS " << model.node_count() << " double\n";
  for (int p = 0; p < model.node_count(); ++p) out << PointText(model, p) << "\n";
  out << "CELLS " << m << " " << 3 * m << "\n";
  for (const auto& s : model.springs) out << "2 " << s.a << " " << s.b << "\n";
  out << "CELL_TYPES " << m << "\n";
  for (std::size_t i = 0; i < m; ++i) out << kVtkLine << "\n";
  out << "CELL_DATA " << m << "\n";
  out << "SCALARS stiffness double 1\nLOOKUP_TABLE default\n";
  for (const auto& s : model.springs) out << ExactNumber(s.stiffness) << "\n";
  out << "SCALARS rest_length double 1\nLOOKUP_TABLE default\n";
  for (const auto& s : model.springs) out << ExactNumber(s.rest_length) << "\n";
  out << "SCALARS identified int 1\nLOOKUP_TABLE default\n";
  for (const auto& s : model.springs) out << (s.identified ? 1 : 0) << "\n";
  return out.str();
}

std::string VtuText(const SpringModel& model) {
  std::ostringstream out;
  const std::size_t m = model.springs.size();
  out << "<?xml version=\"1.0\"?>\n<!-- springfit model " << XmlCommentText(model.name) << ": "
      << XmlCommentText(model.description) << " -->\n"
      << "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
         "header_type=\"UInt64\">\n  <UnstructuredGrid>\n"
      << "    <Piece NumberOfPoints=\"" << model.node_count() << "\" NumberOfCells=\"" << m
      << "\">\n      <Points>\n"
      << "        <DataArray type=\"Float64\" Name=\"rest_position\" NumberOfComponents=\"3\" "
         "format=\"ascii\">\n";
  for (int p = 0; p < model.node_count(); ++p) out << "          " << PointText(model, p) << "\n";
  out << "        </DataArray>\n      </Points>\n      <Cells>\n"
      << "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
  for (const auto& s : model.springs) out << "          " << s.a << " " << s.b << "\n";
  out << "        </DataArray>\n"
      << "        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
  for (std::size_t i = 0; i < m; ++i) out << "          " << 2 * (i + 1) << "\n";
  out << "        </DataArray>\n"
      << "        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (std::size_t i = 0; i < m; ++i) out << "          " << kVtkLine << "\n";
  out << "        </DataArray>\n      </Cells>\n      <CellData Scalars=\"stiffness\">\n";
  const auto array = [&](const char* type, const char* name, auto value) {
    out << "        <DataArray type=\"" << type << "\" Name=\"" << name << "\" format=\"ascii\">\n";
    for (const auto& s : model.springs) out << "          " << value(s) << "\n";
    out << "        </DataArray>\n";
  };
  array("Float64", "stiffness", [](const auto& s) { return ExactNumber(s.stiffness); });
  array("Float64", "rest_length", [](const auto& s) { return ExactNumber(s.rest_length); });
  array("UInt8", "identified", [](const auto& s) { return s.identified ? 1 : 0; });
  out << "      </CellData>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n";
  return out.str();
}

}  // namespace springfit::io
