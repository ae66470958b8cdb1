// FEM reference solves against mesh size, and the FEM examples' reference solves
// (bench/RESULTS.md, "FEM references").
//
//   build/bench/fem_bench                      # 2D and 3D, linear and St. Venant-Kirchhoff
//   build/bench/fem_bench --max-dofs 30000 --dims 3 --models linear
//   build/bench/fem_bench --examples           # the fem-* examples, per load case
//
// Meshes: a square of n x n cells split into triangles (plane stress) and a cube of n^3 cells
// split into six tetrahedra each (engine/examples/simplex_mesh.h), bottom fixed, a total
// traction on the top of 5% of E times the top's area (about 5% strain). Times are wall
// seconds of one run on this machine: setup (model, sparsity pattern and symbolic analysis,
// once per mesh and set of constrained nodes) and the solve of one load case (from rest).
// The growth exponent is the least-squares slope of log(solve time) against log(DOFs) over
// the sizes of at least 5,000 DOFs.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "engine/api/problem.h"
#include "engine/examples/catalog.h"
#include "engine/examples/simplex_mesh.h"
#include "engine/fem/fem_equilibrium.h"
#include "io/example_catalog.h"

namespace springfit {
namespace {

using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

struct Row {
  int dofs = 0;
  double setup = 0.0;
  double solve = 0.0;
};

Scene MeshScene(int d, int n, MaterialModel model) {
  const examples::SimplexMesh mesh = d == 2 ? examples::TriangulatedRectangle(n, n, 1.0, true)
                                            : examples::TetrahedralBlock(n, n, n, 1.0);
  Scene s;
  s.dimension = d;
  s.rest = mesh.nodes;
  s.reference.kind = Reference::Kind::kFem;
  s.reference.fem.elements = mesh.elements;
  s.reference.fem.materials = {Material{model, 1.0, 0.3}};
  s.node_sets["bottom"] = examples::SideNodes(d, s.rest, d - 1, true, 0.0);
  s.node_sets["top"] = examples::SideNodes(d, s.rest, d - 1, false, 0.0);
  LoadCase lc;
  lc.fixed = s.node_sets["bottom"];
  Traction t;
  t.on = "top";
  t.nodes = s.node_sets["top"];
  t.value = Vector::Zero(d);
  t.value[d - 1] = 0.05 * std::pow(static_cast<double>(n), d - 1);  // 5% of E x the top's area
  lc.tractions.push_back(t);
  s.load_cases.push_back(lc);
  return s;
}

fem::FemSolverOptions g_options;  // --backend

Row Measure(const Scene& s, fem::FemSolveSummary& summary) {
  const Problem problem = Problem::Build(s);  // validation, load vectors (and a first solve)
  const PreparedLoadCase& lc = problem.load_cases()[0];
  Row row;
  const auto setup_start = Clock::now();
  const fem::FemModel model = fem::FemModel::Build(s);
  fem::FemEquilibriumSolver solver(model, problem.free_sets()[lc.free_set], g_options);
  row.setup = Seconds(setup_start);
  row.dofs = s.dimension * problem.free_sets()[lc.free_set].count;
  Vector u;
  const auto solve_start = Clock::now();
  summary = solver.Solve(lc.force, lc.prescribed, u);
  row.solve = Seconds(solve_start);
  return row;
}

double GrowthExponent(const std::vector<Row>& rows) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int m = 0;
  for (const Row& r : rows) {
    if (r.dofs < 5000) continue;
    const double x = std::log(r.dofs), y = std::log(r.solve);
    sx += x, sy += y, sxx += x * x, sxy += x * y;
    ++m;
  }
  if (m < 2) return std::nan("");
  return (m * sxy - sx * sy) / (m * sxx - sx * sx);
}

void SizeSweep(int d, MaterialModel model, int max_dofs, const std::vector<int>& cells) {
  std::printf("\n%dD, %s\n%8s %8s %10s %10s %8s %6s\n", d,
              model == MaterialModel::kLinear ? "linear" : "st_venant_kirchhoff", "cells/n", "DOFs",
              "setup s", "solve s", "Newton", "steps");
  std::vector<Row> rows;
  std::vector<int> sizes = cells;
  if (sizes.empty()) {
    for (int n = d == 2 ? 16 : 6; d * std::pow(n + 1.0, d) <= max_dofs * 1.05;
         n = static_cast<int>(std::ceil(n * (d == 2 ? 1.41 : 1.26)))) {
      sizes.push_back(n);
    }
  }
  for (const int n : sizes) {
    fem::FemSolveSummary summary;
    const Row row = Measure(MeshScene(d, n, model), summary);
    rows.push_back(row);
    std::printf("%8d %8d %10.3f %10.3f %8d %6d%s\n", n, row.dofs, row.setup, row.solve,
                summary.iterations, summary.load_steps,
                summary.converged() ? "" : "  NOT CONVERGED");
    std::fflush(stdout);
  }
  std::printf("growth exponent of the solve time (>= 5,000 DOFs): %.2f\n", GrowthExponent(rows));
}

void Examples() {
  std::printf("%-18s %6s %6s %10s %12s %10s %8s\n", "example", "DOFs", "cases", "setup s",
              "solve s/case", "max s", "Newton");
  for (const char* name : {"fem-plate-5x5", "fem-kidney-2d", "fem-kidney-2d-nl", "fem-block-3d"}) {
    const Scene s = examples::Make(name);
    const Problem problem = Problem::Build(s);
    const auto setup_start = Clock::now();
    const fem::FemModel model = fem::FemModel::Build(s);
    std::vector<fem::FemEquilibriumSolver> solvers;
    for (const FreeNodes& free : problem.free_sets()) solvers.emplace_back(model, free, g_options);
    const double setup = Seconds(setup_start);
    double total = 0.0, worst = 0.0;
    int newton = 0;
    for (const PreparedLoadCase& lc : problem.load_cases()) {
      Vector u;
      const auto start = Clock::now();
      newton += solvers[lc.free_set].Solve(lc.force, lc.prescribed, u).iterations;
      const double t = Seconds(start);
      total += t;
      worst = std::max(worst, t);
    }
    const int cases = static_cast<int>(problem.load_cases().size());
    std::printf("%-18s %6d %6d %10.4f %12.4f %10.4f %8.1f\n", name, s.dimension * s.node_count(),
                cases, setup, total / cases, worst, static_cast<double>(newton) / cases);
  }
}

}  // namespace
}  // namespace springfit

int main(int argc, char** argv) {
  CLI::App app{"FEM reference solves against size (bench/RESULTS.md)"};
  int max_dofs = 100000;
  std::vector<int> dims{2, 3};
  std::vector<std::string> models{"linear", "svk"};
  bool examples = false;
  std::vector<int> cells;
  std::string backend = "auto";
  app.add_option("--max-dofs", max_dofs, "Largest mesh, in degrees of freedom (default 100000)");
  app.add_option("--dims", dims, "Dimensions (default 2 3)");
  app.add_option("--models", models, "linear and/or svk (default both)");
  app.add_flag("--examples", examples, "Time the fem-* examples instead");
  app.add_option("--cells", cells, "Cells per side to run (default: a sweep up to --max-dofs)");
  app.add_option("--backend", backend, "auto (FemSolverOptions' rule), simplicial or supernodal")
      ->check(CLI::IsMember({"auto", "simplicial", "supernodal"}));
  CLI11_PARSE(app, argc, argv);
  if (backend == "simplicial") springfit::g_options.supernodal_min_dofs = 1 << 30;
  if (backend == "supernodal") springfit::g_options.supernodal_min_dofs = 0;
  if (examples) {
    springfit::Examples();
    return 0;
  }
  for (int d : dims) {
    for (const std::string& m : models) {
      springfit::SizeSweep(d,
                           m == "svk" ? springfit::MaterialModel::kStVenantKirchhoff
                                      : springfit::MaterialModel::kLinear,
                           max_dofs, cells);
    }
  }
  return 0;
}
