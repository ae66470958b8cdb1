// VTK: the model as an unstructured grid: the springs as line cells (VTK_LINE = 3) with
// per-cell stiffness, rest length and flags, then the FEM mesh's triangles or tetrahedra as
// their own cells (cell_kind 1; the spring data 0 on them), points in 3D (z = 0 for a 2D
// model), and the validation fields per node (model_fields.h).
#include <sstream>

#include "io/model_fields.h"
#include "io/model_writers.h"
#include "io/text_output.h"
#include "io/xml_text.h"

namespace springfit::io {
namespace {

// Point p's three coordinates.
std::string PointText(const SpringModel& model, int p) {
  std::string s;
  for (int c = 0; c < 3; ++c) {
    if (c > 0) s += ' ';
    s += c < model.dimension ? ExactNumber(model.rest[model.dimension * p + c]) : "0";
  }
  return s;
}

// The cells' data: springs first, then mesh elements (which carry 0 and cell_kind 1).
struct CellArray {
  const char* name;
  bool integer;
  double (*of)(const SpringModel::Spring&);
};
constexpr CellArray kCellArrays[] = {
    {"stiffness", false, [](const SpringModel::Spring& s) { return s.stiffness; }},
    {"rest_length", false, [](const SpringModel::Spring& s) { return s.rest_length; }},
    {"identified", true,
     [](const SpringModel::Spring& s) { return static_cast<double>(s.identified); }},
    {"dead", true, [](const SpringModel::Spring& s) { return s.dead ? 1.0 : 0.0; }},
    {"cell_kind", true, [](const SpringModel::Spring&) { return 0.0; }},
};

std::string ValueText(double v, bool integer) {
  return integer ? std::to_string(static_cast<long long>(v)) : ExactNumber(v);
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
  const std::size_t cells = m + model.elements.size();
  std::size_t size = 3 * m;
  for (const auto& e : model.elements) size += 1 + e.size();
  out << "# vtk DataFile Version 3.0\n" << title << "\nASCII\nDATASET UNSTRUCTURED_GRID\n";
  out << "POINTS " << model.node_count() << " double\n";
  for (int p = 0; p < model.node_count(); ++p) out << PointText(model, p) << "\n";
  out << "CELLS " << cells << " " << size << "\n";
  for (const auto& s : model.springs) out << "2 " << s.a << " " << s.b << "\n";
  for (const auto& e : model.elements) {
    out << e.size();
    for (int v : e) out << " " << v;
    out << "\n";
  }
  out << "CELL_TYPES " << cells << "\n";
  for (std::size_t i = 0; i < m; ++i) out << kVtkLine << "\n";
  for (std::size_t i = 0; i < model.elements.size(); ++i)
    out << VtkElementType(model.dimension) << "\n";
  out << "CELL_DATA " << cells << "\n";
  for (const CellArray& a : kCellArrays) {
    out << "SCALARS " << a.name << (a.integer ? " int" : " double") << " 1\nLOOKUP_TABLE default\n";
    for (const auto& s : model.springs) out << ValueText(a.of(s), a.integer) << "\n";
    const double element_value = std::string_view(a.name) == "cell_kind" ? 1.0 : 0.0;
    for (std::size_t i = 0; i < model.elements.size(); ++i)
      out << ValueText(element_value, a.integer) << "\n";
  }
  const std::vector<PointField> fields = PointFieldsOf(model);
  if (!fields.empty()) out << "POINT_DATA " << model.node_count() << "\n";
  for (const PointField& f : fields) {
    if (f.components == 1) {
      out << "SCALARS " << f.name << (f.integer ? " int" : " double")
          << " 1\nLOOKUP_TABLE default\n";
    } else {
      out << "VECTORS " << f.name << " double\n";
    }
    for (int p = 0; p < model.node_count(); ++p) {
      for (int c = 0; c < f.components; ++c)
        out << (c > 0 ? " " : "") << ValueText(f.values[f.components * p + c], f.integer);
      out << "\n";
    }
  }
  return out.str();
}

std::string VtuText(const SpringModel& model) {
  std::ostringstream out;
  const std::size_t m = model.springs.size();
  const std::size_t cells = m + model.elements.size();
  out << "<?xml version=\"1.0\"?>\n<!-- springfit model " << XmlCommentText(model.name) << ": "
      << XmlCommentText(model.description) << " -->\n"
      << "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
         "header_type=\"UInt64\">\n  <UnstructuredGrid>\n"
      << "    <Piece NumberOfPoints=\"" << model.node_count() << "\" NumberOfCells=\"" << cells
      << "\">\n      <Points>\n"
      << "        <DataArray type=\"Float64\" Name=\"rest_position\" NumberOfComponents=\"3\" "
         "format=\"ascii\">\n";
  for (int p = 0; p < model.node_count(); ++p) out << "          " << PointText(model, p) << "\n";
  out << "        </DataArray>\n      </Points>\n      <Cells>\n"
      << "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
  for (const auto& s : model.springs) out << "          " << s.a << " " << s.b << "\n";
  for (const auto& e : model.elements) {
    out << "         ";
    for (int v : e) out << " " << v;
    out << "\n";
  }
  out << "        </DataArray>\n"
      << "        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
  std::size_t offset = 0;
  for (std::size_t i = 0; i < m; ++i) out << "          " << (offset += 2) << "\n";
  for (const auto& e : model.elements) out << "          " << (offset += e.size()) << "\n";
  out << "        </DataArray>\n"
      << "        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (std::size_t i = 0; i < m; ++i) out << "          " << kVtkLine << "\n";
  for (std::size_t i = 0; i < model.elements.size(); ++i)
    out << "          " << VtkElementType(model.dimension) << "\n";
  out << "        </DataArray>\n      </Cells>\n      <CellData Scalars=\"stiffness\">\n";
  for (const CellArray& a : kCellArrays) {
    out << "        <DataArray type=\"" << (a.integer ? "Int64" : "Float64") << "\" Name=\""
        << a.name << "\" format=\"ascii\">\n";
    for (const auto& s : model.springs)
      out << "          " << ValueText(a.of(s), a.integer) << "\n";
    const double element_value = std::string_view(a.name) == "cell_kind" ? 1.0 : 0.0;
    for (std::size_t i = 0; i < model.elements.size(); ++i)
      out << "          " << ValueText(element_value, a.integer) << "\n";
    out << "        </DataArray>\n";
  }
  out << "      </CellData>\n";
  const std::vector<PointField> fields = PointFieldsOf(model);
  if (!fields.empty()) {
    out << "      <PointData>\n";
    for (const PointField& f : fields) {
      out << "        <DataArray type=\"" << (f.integer ? "Int64" : "Float64") << "\" Name=\""
          << XmlEscape(f.name) << "\" NumberOfComponents=\"" << f.components
          << "\" format=\"ascii\">\n";
      for (int p = 0; p < model.node_count(); ++p) {
        out << "         ";
        for (int c = 0; c < f.components; ++c)
          out << " " << ValueText(f.values[f.components * p + c], f.integer);
        out << "\n";
      }
      out << "        </DataArray>\n";
    }
    out << "      </PointData>\n";
  }
  out << "    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n";
  return out.str();
}

}  // namespace springfit::io
