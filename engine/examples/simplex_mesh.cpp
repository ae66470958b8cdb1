#include "engine/examples/simplex_mesh.h"

#include <algorithm>
#include <array>
#include <utility>

namespace springfit::examples {
namespace {

// Swaps two nodes of a simplex whose signed volume is negative.
void Orient(int d, const Vector& x, std::vector<int>& e) {
  Matrix m(d, d);
  for (int a = 0; a < d; ++a) m.col(a) = x.segment(d * e[a + 1], d) - x.segment(d * e[0], d);
  if (m.determinant() < 0.0) std::swap(e[1], e[2]);
}

}  // namespace

SimplexMesh TriangulatedRectangle(int nx, int ny, double h, bool alternate) {
  SimplexMesh mesh;
  mesh.nodes.resize(2 * (nx + 1) * (ny + 1));
  auto id = [&](int i, int j) { return j * (nx + 1) + i; };
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) {
      mesh.nodes[2 * id(i, j)] = i * h;
      mesh.nodes[2 * id(i, j) + 1] = j * h;
    }
  }
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const int a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
      if (!alternate || (i + j) % 2 == 0) {  // '/': diagonal a-c
        mesh.elements.push_back({a, b, c});
        mesh.elements.push_back({a, c, d});
      } else {  // '\': diagonal b-d
        mesh.elements.push_back({a, b, d});
        mesh.elements.push_back({b, c, d});
      }
    }
  }
  for (std::vector<int>& e : mesh.elements) Orient(2, mesh.nodes, e);
  return mesh;
}

SimplexMesh TetrahedralBlock(int nx, int ny, int nz, double h) {
  SimplexMesh mesh;
  mesh.nodes.resize(3 * (nx + 1) * (ny + 1) * (nz + 1));
  auto id = [&](int i, int j, int k) { return (k * (ny + 1) + j) * (nx + 1) + i; };
  for (int k = 0; k <= nz; ++k) {
    for (int j = 0; j <= ny; ++j) {
      for (int i = 0; i <= nx; ++i) {
        mesh.nodes.segment<3>(3 * id(i, j, k)) = Eigen::Vector3d(i * h, j * h, k * h);
      }
    }
  }
  std::array<int, 3> axes = {0, 1, 2};
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        std::sort(axes.begin(), axes.end());
        do {
          // The path from the cube's lowest corner to its highest, one axis at a time.
          std::array<int, 3> c = {i, j, k};
          std::vector<int> tet = {id(c[0], c[1], c[2])};
          for (int axis : axes) {
            ++c[axis];
            tet.push_back(id(c[0], c[1], c[2]));
          }
          mesh.elements.push_back(std::move(tet));
        } while (std::next_permutation(axes.begin(), axes.end()));
      }
    }
  }
  for (std::vector<int>& e : mesh.elements) Orient(3, mesh.nodes, e);
  return mesh;
}

}  // namespace springfit::examples
