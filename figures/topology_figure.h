// The reference and the identified topology side by side under each load case, at rest and
// deformed, wrong springs marked: the figure of Bianchi et al.'s Figures 1 and 3, drawn by
// `springfit render` (README.md, "Figures").
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "engine/api/problem.h"

namespace springfit::figures {

struct TopologyFigureInput {
  std::string title;              // first heading line (scene, strategy, seed)
  std::string note;               // starts the second line, e.g. "cancelled, best so far"
  std::vector<NodePair> springs;  // the identified topology; every pair a candidate
  // Per spring of `springs` (strategy direct identifies it); empty = the scene's training
  // stiffness for every spring.
  std::vector<double> stiffness;
};

struct TopologyFigureOptions {
  std::vector<int> load_cases;  // which load cases, in this order; empty = all
  // Displacements are drawn this many times their size. 0 = automatic: true size when the
  // largest displacement is at least 5% of the scene's diagonal, otherwise enlarged to 10%
  // of it (small-strain scenes would look undeformed). The heading states the factor.
  double magnify = 0.0;
  double panel_size = 340.0;  // pixels, each panel square
  // 3D scenes are drawn in an orthographic view turned by these angles (degrees).
  double azimuth = -35.0;
  double elevation = 25.0;
  // Each node's index beside it (the numbers of the scene, `check` and result files).
  bool node_numbers = false;
  // The two topologies at rest, one pair of panels and no load case, as the paper's Figures
  // 1 and 3 show them: which springs, not how they deform. load_cases and magnify are unused.
  bool rest_topology = false;
};

// Springs whose stiffness differs are drawn with a line width per stiffness: one of
// kStiffnessWidths widths (CSS classes k0 .. k4), by the logarithm of the stiffness over the
// range of the figure's springs, reference and identified together, so that the two panels
// compare. The heading gives the range.
inline constexpr int kStiffnessWidths = 5;

// A 3D point on the page before scaling (y up): an orthographic view turned by `azimuth`
// about the vertical (z) axis and seen from `elevation` degrees above the horizon.
struct ViewPoint {
  double x = 0.0;
  double y = 0.0;
};
ViewPoint ProjectView(double x, double y, double z, double azimuth, double elevation);

// The figure as an SVG document. Missing and extra springs, the normalised error and the
// deformed shapes are computed here from the problem, never taken from a file. Throws
// InputError for a spring that is not a candidate (or given twice), a stiffness list of the
// wrong length or not positive, or a load case index out of range.
std::string RenderTopologyFigure(const Problem& problem, const TopologyFigureInput& input,
                                 const TopologyFigureOptions& options = {});

}  // namespace springfit::figures
