#include "io/example_catalog.h"

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "io/example_meshes.h"
#include "io/mesh_import.h"

namespace springfit::examples {
namespace {

// Removes a temporary file however its scope is left.
struct RemovedOnExit {
  std::string path;
  ~RemovedOnExit() {
    std::error_code ignored;
    std::filesystem::remove(path, ignored);
  }
};

// A mesh built into the program, read by the importer (which reads files: a private temporary
// one). Gmsh writes coordinates with round-off of its own (0.4999999999990952 for 0.5): they
// are rounded to 1e-9, the mesh's designed values, and every triangle is made
// counter-clockwise (SimplexMesh's convention).
SimplexMesh ReadBuiltInMesh(std::string_view text) {
  std::string path =
      (std::filesystem::temp_directory_path() / "springfit-example-XXXXXX.msh").string();
  const int fd = ::mkstemps(path.data(), 4);
  if (fd < 0) throw std::runtime_error("cannot create a temporary file for an example mesh");
  ::close(fd);
  const RemovedOnExit remove{path};
  {
    std::ofstream out(path, std::ios::binary);
    out << text;
    if (!out) throw std::runtime_error("cannot write " + path);
  }
  const io::ImportedMesh mesh = io::ReadGmshMesh(path);
  SimplexMesh result;
  result.nodes.resize(static_cast<Eigen::Index>(mesh.nodes.size()));
  for (std::size_t i = 0; i < mesh.nodes.size(); ++i) {
    const double x = std::round(mesh.nodes[i] * 1e9) / 1e9;
    result.nodes[static_cast<Eigen::Index>(i)] = x == 0.0 ? 0.0 : x;  // no -0
  }
  const auto& p = result.nodes;
  for (std::vector<int> t : mesh.elements) {
    const double area2 = (p[2 * t[1]] - p[2 * t[0]]) * (p[2 * t[2] + 1] - p[2 * t[0] + 1]) -
                         (p[2 * t[1] + 1] - p[2 * t[0] + 1]) * (p[2 * t[2]] - p[2 * t[0]]);
    if (area2 < 0.0) std::swap(t[1], t[2]);
    result.elements.push_back(std::move(t));
  }
  return result;
}

}  // namespace

const SimplexMesh& KidneyMesh() {
  static const SimplexMesh mesh = ReadBuiltInMesh(kKidneyMsh);
  return mesh;
}

const SimplexMesh& KidneyMeshFine() {
  static const SimplexMesh mesh = ReadBuiltInMesh(kKidneyFineMsh);
  return mesh;
}

const std::vector<ExampleInfo>& Catalog() {
  static const std::vector<ExampleInfo> catalog = [] {
    std::vector<ExampleInfo> c;
    for (const char* name : {"paper-iso-5x5", "paper-aniso-5x5", "kidney-2d", "grid3d-4x4x4",
                             "stiff-2d", "fem-plate-5x5", "fem-kidney-2d", "fem-kidney-2d-nl",
                             "fem-kidney-2d-fine", "fem-block-3d"}) {
      c.push_back({name, Make(name).description});
    }
    return c;
  }();
  return catalog;
}

Scene Make(const std::string& name) {
  if (name == "paper-iso-5x5") return PaperGrid(name, false);
  if (name == "paper-aniso-5x5") return PaperGrid(name, true);
  if (name == "kidney-2d") return Kidney2d(KidneyMesh());
  if (name == "grid3d-4x4x4") return Grid3d();
  if (name == "stiff-2d") return Stiff2d();
  if (name == "fem-plate-5x5") return FemPlate5x5();
  if (name == "fem-kidney-2d") return FemKidney2d(KidneyMesh(), false);
  if (name == "fem-kidney-2d-nl") return FemKidney2d(KidneyMesh(), true);
  if (name == "fem-kidney-2d-fine") return FemKidney2dFine(KidneyMeshFine());
  if (name == "fem-block-3d") return FemBlock3d();
  throw std::invalid_argument("unknown example '" + name + "'");
}

}  // namespace springfit::examples
