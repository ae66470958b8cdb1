#include "engine/scene.h"

namespace springfit {

double Scene::EffectiveTrainingStiffness() const {
  if (training_stiffness) return *training_stiffness;
  if (reference.kind == Reference::Kind::kMss && reference.stiffness.size() == 1) {
    return reference.stiffness.front();
  }
  return 1.0;
}

}  // namespace springfit
