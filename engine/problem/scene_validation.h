// The semantic rules of a scene, checked once at the boundary.
#pragma once

#include <utility>

#include "engine/model/scene.h"

namespace springfit {

// Throws InputError naming the JSON path of the first broken rule:
// - dimension 2 or 3; at least two nodes; finite coordinates; no two nodes at the same
//   position (closer than 1e-9 of the scene's extent);
// - candidate spec: k >= 1, radius > 0, spacing > 0 with one value per axis, pairs in range,
//   no self or duplicate pairs;
// - reference MSS springs in range, no self or duplicate springs, stiffness finite and > 0,
//   one value or one per spring; reference positions: one configuration per load case, each
//   with every node, finite;
// - at least one load case; node indices in range; a node at most once among a case's fixed
//   and displaced nodes; forces only on free nodes; vectors of the scene's dimension and finite;
//   every case applies some nonzero force or displacement; the constrained nodes of every case
//   remove rigid motion (two nodes in 2D, three not on one line in 3D);
// - training stiffness finite and > 0; search settings within their documented ranges.
void ValidateScene(const Scene& scene);

// A scene that passed ValidateScene: what prepares it (Problem) does not check it again. A
// submission is validated at the door, in time linear in its size, and prepared after.
class ValidScene {
 public:
  // Validates `scene` (ValidateScene); throws InputError.
  explicit ValidScene(Scene scene) : scene_(std::move(scene)) { ValidateScene(scene_); }
  const Scene& scene() const { return scene_; }
  Scene Release() && { return std::move(scene_); }

 private:
  Scene scene_;
};

}  // namespace springfit
