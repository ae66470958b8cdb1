// Whether a linear FEM reference is still a small-strain model at the loads a simulator applies
// (docs/ARCHITECTURE.md, "Judging a model as the simulator runs it"). A linear material's
// response is the small-load limit of tissue: past a few percent of strain (or of rotation) it
// misjudges both, and a model fitted to it inherits the error. The check runs on the named
// cases' responses scaled to the load range (search.load_size, else the named loads' size), so
// it costs one pass over the elements per case and no solve.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "engine/linalg/linalg.h"

namespace springfit {

class Problem;

// Past this principal Green-Lagrange strain, about 2 %, the linear theory's error is of the
// order of the strain itself: the reference no longer describes the tissue it stands for.
inline constexpr double kSmallStrainLimit = 0.02;
// The strain judged is the one exceeded in this fraction of the body's volume, not the largest
// element's: under a point force a linear mesh's strain is singular at the node (it grows as the
// mesh is refined: 10 % on the kidney, 20 % on the fine kidney under the same loads), while the
// body around it stays small. 5 % of the volume is the part a simulator's user sees deform.
inline constexpr double kStrainedVolumeFraction = 0.05;

// The largest nodal displacement of `u` (flat d*n).
double LargestNodalDisplacement(int d, const Vector& u);
// The size of a set of loads: the median over their responses of the largest nodal
// displacement; 0 for none. The one rule for the named loads' size, here and in the probe bank.
double LoadsSize(int d, const std::vector<const Vector*>& responses);
// The named loads' size: LoadsSize of the reference's responses to the named cases (for a
// linear FEM reference the probe bank's amplitude, probe_bank.h). 0 when no case moves a node.
double NamedLoadsSize(const Problem& problem);

// The strain of a linear FEM reference's named cases, each response scaled by `load_scale` (a
// linear response scales with its load): per case, the principal Green-Lagrange strain
// exceeded in kStrainedVolumeFraction of the volume; the case where it is largest.
struct ReferenceStrain {
  double strain = 0.0;   // exceeded in kStrainedVolumeFraction of the volume
  double largest = 0.0;  // the largest element's, in the same case
  int load_case = -1;
  int element = -1;  // the largest element
};
// Absent for a reference that is not a linear FEM (a nonlinear material follows the strain
// itself; a positions or MSS reference has no continuum strain).
std::optional<ReferenceStrain> LinearReferenceStrain(const Problem& problem,
                                                     double load_scale = 1.0);

// SmallStrainWarning, the one line `run` and `check` print, is on the surface
// (engine/api/problem.h).

}  // namespace springfit
