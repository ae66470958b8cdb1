// The built-in examples whose reference is a finite-element model (catalog.h).
#include <stdexcept>

#include "engine/examples/catalog.h"
#include "engine/examples/simplex_mesh.h"

namespace springfit::examples {
namespace {

// Young's modulus of the examples' tissue: stiffness scales out of the normalised error, so
// 1 (in the scene's force per area) loses nothing.
constexpr double kYoung = 1.0;
// Loads of the FEM examples: the largest nodal displacement is this fraction of the scene's
// extent in the small-load limit (docs/ARCHITECTURE.md, "Paper7 load cases"). A linear material
// is the small-load limit of tissue, so its examples stay within small strain (under 2 % in
// all but a few elements at the loaded ends: engine/problem/small_strain.h; at 5 % of the
// extent the kidney strained 8.5 %); the nonlinear kidney is loaded to a moderate strain, where
// its material's nonlinearity shows.
constexpr double kLinearStrain = 0.01;
constexpr double kNonlinearStrain = 0.05;

// The paper7 patterns as load cases on node sets: the fixed side held, a total traction on
// the loaded side's boundary edges (faces), before ScaleLoadsToStrain sets its size.
void AddPaper7Tractions(Scene& s, double band) {
  const int d = s.dimension;
  const char* low_names[] = {"left", d == 2 ? "bottom" : "front", "bottom"};
  const char* high_names[] = {"right", d == 2 ? "top" : "back", "top"};
  for (const Paper7Pattern& p : Paper7Patterns(d)) {
    const std::string low = low_names[p.fixed_axis], high = high_names[p.fixed_axis];
    s.node_sets[low] = SideNodes(d, s.rest, p.fixed_axis, true, band);
    s.node_sets[high] = SideNodes(d, s.rest, p.fixed_axis, false, band);
    LoadCase lc;
    lc.name = p.name;
    lc.fixed = s.node_sets[low];
    lc.fixed_set = low;
    Traction t;
    t.on = high;
    t.nodes = s.node_sets[high];
    t.value = Vector::Zero(d);  // not Unit() * sign: that writes -0.0 components
    t.value[p.load_axis] = p.sign;
    lc.tractions.push_back(std::move(t));
    s.load_cases.push_back(std::move(lc));
  }
}

// The paper7 tractions scaled to `strain`, and the check that no element inverts under them.
void AddLoads(Scene& s, const SimplexMesh& mesh, double band, double strain) {
  AddPaper7Tractions(s, band);
  ScaleLoadsToStrain(s, strain);
  CheckFoldFree(s, mesh.elements);
}

Scene FemScene(const std::string& name, const std::string& description, const SimplexMesh& mesh,
               int d, Material material, int k) {
  Scene s;
  s.name = name;
  s.description = description;
  s.dimension = d;
  s.rest = mesh.nodes;
  s.candidates.kind = CandidateSpec::Kind::kMesh;
  s.candidates.k = k;
  s.reference.kind = Reference::Kind::kFem;
  s.reference.fem.elements = mesh.elements;
  s.reference.fem.materials = {material};
  return s;
}

// A kidney cross-section scene: poisson 0.45, plane strain, mesh edges and 8 nearest
// neighbours, paper7 tractions on the ends (a band of 0.12 of the extent).
Scene KidneyScene(const std::string& name, const std::string& description, const SimplexMesh& mesh,
                  MaterialModel model) {
  Scene s = FemScene(name, description, mesh, 2, Material{model, kYoung, 0.45}, 8);
  s.reference.fem.plane = PlaneMode::kStrain;
  s.reference.fem.plane_given = true;
  AddLoads(s, mesh, 0.12, model == MaterialModel::kLinear ? kLinearStrain : kNonlinearStrain);
  return s;
}

}  // namespace

Scene FemPlate5x5() {
  const SimplexMesh mesh = TriangulatedRectangle(4, 4, 1.0, false);
  Scene s = FemScene("fem-plate-5x5",
                     "5x5-node plate, 32 triangles (every '/' diagonal), linear elastic, poisson "
                     "0.3, plane stress; "
                     "candidates: mesh edges and 8 nearest neighbours; the paper's seven load "
                     "cases as tractions "
                     "moving it by 1% of its size",
                     mesh, 2, Material{MaterialModel::kLinear, kYoung, 0.3}, 8);
  s.reference.fem.plane = PlaneMode::kStress;
  s.reference.fem.plane_given = true;
  AddLoads(s, mesh, 0.0, kLinearStrain);
  return s;
}

Scene FemKidney2d(const SimplexMesh& mesh, bool nonlinear) {
  return KidneyScene(
      nonlinear ? "fem-kidney-2d-nl" : "fem-kidney-2d",
      std::string("kidney cross-section meshed by gmsh (99 nodes, 165 triangles), ") +
          (nonlinear ? "St. Venant-Kirchhoff" : "linear elastic") +
          ", poisson 0.45, plane strain; candidates: mesh edges and 8 nearest neighbours; paper7 "
          "loads as tractions on opposite ends moving it by " +
          (nonlinear ? "5" : "1") + "% of its size",
      mesh, nonlinear ? MaterialModel::kStVenantKirchhoff : MaterialModel::kLinear);
}

Scene FemKidney2dFine(const SimplexMesh& mesh) {
  return KidneyScene(
      "fem-kidney-2d-fine",
      "kidney cross-section meshed finer by gmsh (626 nodes, 1164 triangles), "
      "linear elastic, poisson 0.45, plane strain; candidates: mesh edges and 8 "
      "nearest neighbours; paper7 loads as tractions on opposite ends moving it by 1% "
      "of its size",
      mesh, MaterialModel::kLinear);
}

Scene FemBlock3d() {
  const SimplexMesh mesh = TetrahedralBlock(12, 8, 8, 1.0);
  Scene s = FemScene(
      "fem-block-3d",
      "13x9x9-node block (1053 nodes, 4608 tetrahedra), linear elastic, poisson 0.3; candidates: "
      "mesh edges and 6 nearest neighbours; paper7 extended to 3D as tractions moving it by 1% of "
      "its size",
      mesh, 3, Material{MaterialModel::kLinear, kYoung, 0.3}, 6);
  AddLoads(s, mesh, 0.0, kLinearStrain);
  return s;
}

}  // namespace springfit::examples
