#include "engine/api/scene.h"

#include <algorithm>

namespace springfit {

BoundingBox BoundingBox::Of(int dimension, const Vector& flat_points) {
  BoundingBox box{flat_points.segment(0, dimension), flat_points.segment(0, dimension)};
  for (Eigen::Index i = dimension; i < flat_points.size(); i += dimension) {
    box.lo = box.lo.cwiseMin(flat_points.segment(i, dimension));
    box.hi = box.hi.cwiseMax(flat_points.segment(i, dimension));
  }
  return box;
}

namespace {

// The reference MSS's springs do not all have one stiffness.
bool PerSpringStiffness(const Reference& r) {
  return r.kind == Reference::Kind::kMss && r.stiffness.size() > 1 &&
         std::any_of(r.stiffness.begin(), r.stiffness.end(),
                     [&](double k) { return k != r.stiffness.front(); });
}

}  // namespace

Strategy ResolvedStrategy(Strategy strategy, const Scene& scene) {
  if (strategy != Strategy::kDefault) return strategy;
  if (scene.reference.kind == Reference::Kind::kFem) return Strategy::kContinuous;
  const std::optional<Identify>& identify = scene.search.identify;
  if (identify == Identify::kTopologyAndStiffness ||
      (!identify && PerSpringStiffness(scene.reference)))
    return Strategy::kDirect;
  return Strategy::kHybrid;
}

const char* DefaultStrategyReason(Strategy strategy, const Scene& scene) {
  if (strategy != Strategy::kDefault) return "";
  switch (ResolvedStrategy(strategy, scene)) {
    case Strategy::kContinuous:
      return "an FEM reference: each spring's stiffness is fitted, starting from the closed-form "
             "spring model of the mesh";
    case Strategy::kDirect:
      return scene.search.identify
                 ? "topology_and_stiffness asked for: the force balance gives both at once"
                 : "the reference's springs differ in stiffness, which springs of one training "
                   "stiffness cannot reproduce: the force balance identifies each one's";
    default:
      return "the topology at one training stiffness: the force balance's topology seeds a "
             "memetic genetic search";
  }
}

double Scene::EffectiveTrainingStiffness() const {
  if (training_stiffness) return *training_stiffness;
  if (reference.kind == Reference::Kind::kMss && reference.stiffness.size() == 1) {
    return reference.stiffness.front();
  }
  return 1.0;
}

}  // namespace springfit
