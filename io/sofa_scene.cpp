// SOFA: every model is written with Vec3d coordinates, a 2D one at z = 0 with its nodes held
// along z: DiagonalMass, the only component taking a mass per node as given, has no Vec2d
// variant before v26.06 (DiagonalMass<Vec2,Vec3> needs a 3D geometry state).
#include "io/sofa_scene.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <fmt/format.h>

#include "engine/api/analysis.h"
#include "engine/api/input_error.h"
#include "io/model_facts.h"
#include "io/text_output.h"
#include "io/xml_text.h"

namespace springfit::io {
namespace {

// A release as SOFA names it ("v24.06") or without its "v" ("24.06"), as users write it.
int ReleaseIndex(const std::string& release) {
  const std::string named = !release.empty() && release[0] != 'v' ? "v" + release : release;
  for (std::size_t i = 0; i < kSofaReleases.size(); ++i)
    if (named == kSofaReleases[i]) return static_cast<int>(i);
  return -1;
}

std::string KnownReleases() {
  std::string s;
  for (const char* r : kSofaReleases) s += (s.empty() ? "" : ", ") + std::string(r);
  return s;
}

// Node p's position in 3D from a flat vector of `d` per node.
void Point(std::ostream& out, const std::vector<double>& x, int d, int p) {
  for (int c = 0; c < 3; ++c)
    out << (c > 0 ? " " : "")
        << (c < d ? ExactNumber(x[static_cast<std::size_t>(d * p + c)]) : "0");
}

}  // namespace

void SofaOptions::Validate() const {
  if (ReleaseIndex(release) < 0)
    throw InputError("--sofa-version",
                     "unknown SOFA release '" + release + "' (known: " + KnownReleases() + ")");
  if (!(rayleigh_stiffness >= 0.0) || !std::isfinite(rayleigh_stiffness))
    throw InputError("--rayleigh-stiffness", "must be a finite number >= 0");
  if (!(rayleigh_mass >= 0.0) || !std::isfinite(rayleigh_mass))
    throw InputError("--rayleigh-mass", "must be a finite number >= 0");
  if (!(time_step > 0.0) || !std::isfinite(time_step))
    throw InputError("--dt", "must be a finite number > 0");
  for (double g : gravity)
    if (!std::isfinite(g)) throw InputError("--gravity", "must be finite");
  if (newton_iterations < 1) throw InputError("--newton-iterations", "must be >= 1");
}

SofaComponents SofaComponentsOf(const std::string& release) {
  const int i = ReleaseIndex(release);
  if (i < 0) throw InputError("--sofa-version", "unknown SOFA release '" + release + "'");
  const bool from_24_06 = i >= ReleaseIndex("v24.06");
  const bool from_24_12 = i >= ReleaseIndex("v24.12");
  return {from_24_12 ? "SpringForceField" : "StiffSpringForceField",
          from_24_06 ? "FixedProjectiveConstraint" : "FixedConstraint",
          from_24_06 ? "PartialFixedProjectiveConstraint" : "PartialFixedConstraint",
          i >= ReleaseIndex("v25.06")};
}

namespace {

// Text safe inside an XML comment, which may not hold "--" (a result's reason comes from its
// JSON, which anyone can write).
std::string XmlCommentText(std::string text) {
  for (std::size_t at = text.find("--"); at != std::string::npos; at = text.find("--", at))
    text.replace(at, 2, "- -");
  return text;
}

std::string Number(double x) {
  return ExactNumber(x);
}

// The load case the scene applies: --case, else the first.
const SpringModel::LoadCase& ChosenLoadCase(const SpringModel& model, const SofaOptions& options) {
  if (model.load_cases.empty()) throw InputError("--case", "the scene has no load case");
  if (options.load_case.empty()) return model.load_cases.front();
  const auto it = std::find_if(model.load_cases.begin(), model.load_cases.end(),
                               [&](const auto& c) { return c.name == options.load_case; });
  if (it == model.load_cases.end()) {
    std::string names;
    for (const auto& c : model.load_cases) names += (names.empty() ? "'" : ", '") + c.name + "'";
    throw InputError("--case",
                     "no load case '" + options.load_case + "' (the scene's: " + names + ")");
  }
  return *it;
}

// The nodes whose predicted displacement a scene states (SofaScene::WritePrediction).
constexpr std::size_t kMonitoredNodes = 5;

// What one SOFA scene is written from: the model, the options, the load case, and the scales of
// the solver's stopping tests (the body's size and the load's size).
struct SofaScene {
  const SpringModel& model;
  const SofaOptions& options;
  const SofaComponents parts;
  const SpringModel::LoadCase& lc;
  bool masses = false;
  double size = 0.0;
  double force_scale = 0.0;
  std::vector<int> loaded;  // the nodes the case puts a force on

  SofaScene(const SpringModel& m, const SofaOptions& o)
      : model(m), options(o), parts(SofaComponentsOf(o.release)), lc(ChosenLoadCase(m, o)) {
    masses = !model.mass.empty();
    const bool gravity = std::any_of(options.gravity.begin(), options.gravity.end(),
                                     [](double g) { return g != 0.0; });
    if ((options.dynamic || gravity) && !masses) {
      throw InputError(options.dynamic ? "--dynamic" : "--gravity",
                       "needs the nodes' masses: give the material's density in the scene, "
                       "--density (lumped on the mesh) or --node-mass");
    }
    const int d = model.dimension;
    const int n = model.node_count();
    for (int c = 0; c < d; ++c) {
      double lo = model.rest[static_cast<std::size_t>(c)], hi = lo;
      for (int p = 0; p < n; ++p) {
        lo = std::min(lo, model.rest[static_cast<std::size_t>(d * p + c)]);
        hi = std::max(hi, model.rest[static_cast<std::size_t>(d * p + c)]);
      }
      size = std::max(size, hi - lo);
    }
    for (int p = 0; p < n; ++p) {
      double f2 = 0.0;
      for (int c = 0; c < d; ++c) f2 += std::pow(lc.force[static_cast<std::size_t>(d * p + c)], 2);
      if (f2 > 0.0) loaded.push_back(p);
      force_scale = std::max(force_scale, std::sqrt(f2));
    }
    if (force_scale == 0.0) force_scale = 1.0;  // a case of prescribed displacements alone
  }

  // The comment that says what the scene is, and the root node with its plugins.
  void WriteHeader(std::ostream& out) const {
    out << "<?xml version=\"1.0\"?>\n<!-- springfit model " << XmlCommentText(model.name) << ": "
        << XmlCommentText(model.description) << ".\n     SOFA "
        << kSofaReleases[static_cast<std::size_t>(ReleaseIndex(options.release))]
        << " (the release chosen at export; components as that release names them, "
           "proto/MODEL.md).\n     Load case '"
        << XmlCommentText(lc.name) << "': " << lc.held.size() << " held nodes, " << loaded.size()
        << " loaded nodes. "
        << (options.dynamic ? "Dynamic: implicit Euler, Rayleigh damping " +
                                  Number(options.rayleigh_stiffness) + " K + " +
                                  Number(options.rayleigh_mass) + " M."
                            : "Static: Newton iterations to the equilibrium.")
        << "\n     Masses: "
        << (masses ? XmlCommentText(model.mass_source)
                   : std::string("none (a static solve needs none)"))
        << ".";
    if (model.facts.stable_time_step)
      out << " Stable explicit time step at most " << Number(*model.facts.stable_time_step)
          << (model.units ? " " + model.units->time : std::string()) << " (undamped).";
    out << "\n     How it was " << XmlCommentText(JudgedText(model)) << ".";
    if (model.dimension == 2) out << "\n     2D model: Vec3d at z = 0, every node held along z.";
    out << " -->\n";
    out << "<Node name=\"root\" gravity=\"" << Number(options.gravity[0]) << " "
        << Number(options.gravity[1]) << " " << Number(options.gravity[2]) << "\" dt=\""
        << Number(options.time_step) << "\">\n";
    std::vector<std::string> plugins = {
        "Sofa.Component.StateContainer",        "Sofa.Component.Topology.Container.Dynamic",
        "Sofa.Component.SolidMechanics.Spring", "Sofa.Component.Constraint.Projective",
        "Sofa.Component.ODESolver.Backward",    "Sofa.Component.LinearSolver.Direct"};
    if (!loaded.empty()) plugins.push_back("Sofa.Component.MechanicalLoad");
    if (masses) plugins.push_back("Sofa.Component.Mass");
    for (const auto& p : plugins) out << "  <RequiredPlugin name=\"" << p << "\"/>\n";
    out << "  <DefaultAnimationLoop/>\n";
  }

  // What springfit predicts this scene computes: the displacement of the nodes that move most,
  // from springfit's solve of the same springs with SOFA's law (f = k (l - L0) along the current
  // direction: nonlinear springs), as a comment a user compares SOFA's result with, and one line
  // per node (`springfit-expected NODE UX UY UZ`) a script reads.
  void WritePrediction(std::ostream& out) const {
    const int d = model.dimension;
    const int n = model.node_count();
    out << "<!-- What this scene should compute (springfit's prediction): the equilibrium of these "
           "springs\n     under load case '"
        << XmlCommentText(lc.name)
        << "', solved by springfit with SOFA's spring law (f = k (l - L0) along the current "
           "direction:\n     nonlinear springs, as every release here runs them), the same "
           "supports and forces.\n";
    if (lc.model_displacement.empty()) {
      out << "     None: the springs have no equilibrium under this case (a mechanism, or a "
             "load they cannot carry). -->\n";
      return;
    }
    if (std::any_of(options.gravity.begin(), options.gravity.end(),
                    [](double g) { return g != 0.0; })) {
      out << "     None here: this scene adds gravity, which springfit's solve of the "
             "case does not;\n     export without gravity for a scene whose equilibrium is "
             "stated. -->\n";
      return;
    }
    std::vector<std::pair<double, int>> by_size;
    for (int p = 0; p < n; ++p) {
      double u2 = 0.0;
      for (int c = 0; c < d; ++c)
        u2 += std::pow(lc.model_displacement[static_cast<std::size_t>(d * p + c)], 2);
      by_size.emplace_back(-u2, p);
    }
    const std::size_t shown = std::min<std::size_t>(kMonitoredNodes, by_size.size());
    std::partial_sort(by_size.begin(), by_size.begin() + static_cast<std::ptrdiff_t>(shown),
                      by_size.end());
    out << "     Compare each node's displacement from rest (position - rest_position) after "
        << (options.dynamic ? "the motion settles" : "the static solve")
        << ": the relative difference\n     |u_SOFA - u| / |u| should be at most 1e-6 (the "
           "Newton tolerances below); a larger one means the scene\n     was changed or SOFA's "
           "springs differ from the law above. The "
        << shown << " nodes that move most (node, u x y z):\n";
    for (std::size_t i = 0; i < shown; ++i) {
      const int p = by_size[i].second;
      out << "     springfit-expected " << p;
      for (int c = 0; c < 3; ++c)
        out << " "
            << (c < d ? ExactNumber(lc.model_displacement[static_cast<std::size_t>(d * p + c)])
                      : "0");
      out << "\n";
    }
    out << "-->\n";
  }

  // The time integration (implicit Euler) or the static Newton solve, and the linear solver.
  void WriteSolver(std::ostream& out) const {
    const auto short_number = [](double x) { return fmt::format("{:.3g}", x); };
    const std::string residual = short_number(1e-12 * force_scale);
    const std::string correction = short_number(1e-12 * (size > 0.0 ? size : 1.0));
    if (options.dynamic) {
      out << "    <EulerImplicitSolver name=\"odesolver\" rayleighStiffness=\""
          << Number(options.rayleigh_stiffness) << "\" rayleighMass=\""
          << Number(options.rayleigh_mass) << "\"/>\n";
    } else if (parts.newton_raphson_component) {
      out << "    <NewtonRaphsonSolver name=\"newton\" maxNbIterationsNewton=\""
          << options.newton_iterations << "\" absoluteResidualStoppingThreshold=\"" << residual
          << "\" relativeInitialStoppingThreshold=\"1e-12\" absoluteEstimateDifferenceThreshold=\""
          << correction << "\" relativeEstimateDifferenceThreshold=\"1e-12\"/>\n"
          << "    <StaticSolver name=\"odesolver\" newtonSolver=\"@newton\"/>\n";
    } else {
      out << "    <StaticSolver name=\"odesolver\" newton_iterations=\""
          << options.newton_iterations << "\" absolute_residual_tolerance_threshold=\"" << residual
          << "\" relative_residual_tolerance_threshold=\"1e-12\" "
             "absolute_correction_tolerance_threshold=\""
          << correction << "\" relative_correction_tolerance_threshold=\"1e-12\"/>\n";
    }
    out << "    <SparseLDLSolver name=\"linearsolver\" "
           "template=\"CompressedRowSparseMatrixMat3x3d\"/>\n";
  }

  // Topology (its points: every node, also those no spring holds), state, mass.
  void WriteBody(std::ostream& out) const {
    const int d = model.dimension;
    const int n = model.node_count();
    const auto points = [&](const std::vector<double>& flat) {
      for (int p = 0; p < n; ++p) {
        if (p > 0) out << "  ";
        Point(out, flat, d, p);
      }
    };
    out << "    <EdgeSetTopologyContainer name=\"topology\" position=\"";
    points(model.rest);
    out << "\" edges=\"";
    for (std::size_t i = 0; i < model.springs.size(); ++i)
      out << (i > 0 ? "  " : "") << model.springs[i].a << " " << model.springs[i].b;
    out << "\"/>\n    <MechanicalObject name=\"dofs\" template=\"Vec3d\" position=\"";
    points(lc.start);
    out << "\" rest_position=\"";
    points(model.rest);
    out << "\"/>\n";
    if (!masses) return;
    const bool uniform = std::all_of(model.mass.begin(), model.mass.end(),
                                     [&](double m) { return m == model.mass.front(); });
    if (uniform) {
      out << "    <UniformMass name=\"mass\" vertexMass=\"" << Number(model.mass.front())
          << "\"/>\n";
    } else {
      out << "    <DiagonalMass name=\"mass\" vertexMass=\"";
      for (int p = 0; p < n; ++p)
        out << (p > 0 ? " " : "") << Number(model.mass[static_cast<std::size_t>(p)]);
      out << "\"/>\n";
    }
  }

  // Springs: "index1 index2 stiffness damping rest_length" each (SOFA's LinearSpring), and
  // which of them the load cases do not determine (SOFA has no per-spring flag: a comment).
  void WriteSprings(std::ostream& out) const {
    out << "    <" << parts.springs << " name=\"springs\" template=\"Vec3d\" spring=\"";
    for (std::size_t i = 0; i < model.springs.size(); ++i) {
      const auto& s = model.springs[i];
      out << (i > 0 ? "  " : "") << s.a << " " << s.b << " " << Number(s.stiffness) << " 0 "
          << Number(s.rest_length);
    }
    out << "\"/>\n";
    std::string flagged;
    bool not_analysed = false;
    for (std::size_t i = 0; i < model.springs.size(); ++i) {
      if (model.springs[i].identified == SpringModel::Identified::kNo)
        flagged += " " + std::to_string(i);
      not_analysed =
          not_analysed || model.springs[i].identified == SpringModel::Identified::kNotAnalysed;
    }
    if (!flagged.empty()) {
      out << "    <!-- springs (0-based, in the order above) whose stiffness the load cases do "
             "not determine:"
          << flagged << " -->\n";
    }
    if (not_analysed) {
      out << "    <!-- whether the load cases determine the other springs' stiffness was not "
             "analysed: dependent groups "
          << XmlCommentText(GroupsNotAnalysedText(model.groups_not_analysed)) << " -->\n";
    }
  }

  // Supports and loads of the case.
  void WriteSupportsAndLoads(std::ostream& out) const {
    if (!lc.held.empty()) {
      out << "    <" << parts.fixed << " name=\"supports\" indices=\"";
      for (std::size_t i = 0; i < lc.held.size(); ++i) out << (i > 0 ? " " : "") << lc.held[i];
      out << "\"/>\n";
    }
    if (model.dimension == 2) {
      out << "    <" << parts.partial_fixed
          << " name=\"plane\" fixAll=\"1\" fixedDirections=\"0 0 1\"/>\n";
    }
    if (!loaded.empty()) {
      out << "    <ConstantForceField name=\"loads\" indices=\"";
      for (std::size_t i = 0; i < loaded.size(); ++i) out << (i > 0 ? " " : "") << loaded[i];
      out << "\" forces=\"";
      for (std::size_t i = 0; i < loaded.size(); ++i) {
        if (i > 0) out << "  ";
        Point(out, lc.force, model.dimension, loaded[i]);
      }
      out << "\"/>\n";
    }
  }
};

}  // namespace

std::string SofaSceneText(const SpringModel& model, const SofaOptions& options) {
  options.Validate();
  const SofaScene scene(model, options);
  std::ostringstream out;
  scene.WriteHeader(out);
  scene.WritePrediction(out);
  out << "  <Node name=\"" << XmlEscape(model.name) << "\">\n";
  scene.WriteSolver(out);
  scene.WriteBody(out);
  scene.WriteSprings(out);
  scene.WriteSupportsAndLoads(out);
  out << "  </Node>\n</Node>\n";
  return out.str();
}

}  // namespace springfit::io
