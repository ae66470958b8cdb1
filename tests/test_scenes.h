// Small scenes and helpers shared by the tests.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "engine/api/problem.h"
#include "engine/api/scene.h"

namespace springfit::testing {

// An n x n (x n) grid of spacing h, 8/26-neighbourhood grid candidates, reference = every
// candidate with stiffness k, paper7 loads of `magnitude` per loaded node.
Scene GridScene(int dimension, int n, double h = 1.0, double k = 1.0, double magnitude = 0.05);

// A grid whose nodes are moved by up to `jitter` x spacing (deterministic in `seed`), with
// nearest-neighbour candidates: an irregular mesh for sparse-vs-dense and derivative checks.
Scene JitteredScene(int dimension, int n, double jitter, std::uint32_t seed);

// A deterministic pseudo-random number in [0, 1) (a tiny LCG; tests own their randomness).
class TestRandom {
 public:
  explicit TestRandom(std::uint64_t seed)
      : state_(seed * 6364136223846793005ULL + 1442695040888963407ULL) {}
  double Uniform() {
    state_ = state_ * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(state_ >> 11) * (1.0 / 9007199254740992.0);
  }

 private:
  std::uint64_t state_;
};

// The scene with every length (node positions, spacing, radius, prescribed displacements)
// and force multiplied by s: stiffness unchanged, so displacements scale by s.
Scene ScaledScene(const Scene& scene, double s);

}  // namespace springfit::testing
