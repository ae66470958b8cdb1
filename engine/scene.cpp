#include "engine/scene.h"

namespace springfit {

BoundingBox BoundingBox::Of(int dimension, const Vector& flat_points) {
  BoundingBox box{flat_points.segment(0, dimension), flat_points.segment(0, dimension)};
  for (Eigen::Index i = dimension; i < flat_points.size(); i += dimension) {
    box.lo = box.lo.cwiseMin(flat_points.segment(i, dimension));
    box.hi = box.hi.cwiseMax(flat_points.segment(i, dimension));
  }
  return box;
}

Strategy ResolvedStrategy(Strategy strategy, Reference::Kind reference) {
  if (strategy != Strategy::kDefault) return strategy;
  return reference == Reference::Kind::kFem ? Strategy::kContinuous : Strategy::kHybrid;
}

double Scene::EffectiveTrainingStiffness() const {
  if (training_stiffness) return *training_stiffness;
  if (reference.kind == Reference::Kind::kMss && reference.stiffness.size() == 1) {
    return reference.stiffness.front();
  }
  return 1.0;
}

}  // namespace springfit
