// The search's random stream.
//
// The generator is std::mt19937_64, whose output sequence the C++ standard fixes for every
// implementation. The standard *distributions* are not fixed (libstdc++ and libc++ map the
// same bits to different numbers), so every mapping from bits to a draw is defined here:
// a seed gives the same draws with every compiler and library. The state can be saved as
// text and restored, so a checkpoint resumes the same stream.
#pragma once

#include <cstdint>
#include <random>
#include <string>

namespace springfit {

class RandomStream {
 public:
  explicit RandomStream(std::uint64_t seed = 1) : engine_(seed) {}

  std::uint64_t NextBits() { return engine_(); }
  // Uniform on [0, 1) with 53 random bits.
  double Uniform();
  // Uniform integer in [0, n), n >= 1, without modulo bias (rejection of the short low band).
  std::uint64_t Below(std::uint64_t n);
  int Below(int n) { return static_cast<int>(Below(static_cast<std::uint64_t>(n))); }
  // True with probability p (Uniform() < p: p = 0 never, p = 1 always).
  bool Bernoulli(double p) { return Uniform() < p; }

  // The complete state as text (the standard's operator<< format of the engine), and back.
  std::string SaveState() const;
  void RestoreState(const std::string& state);

 private:
  std::mt19937_64 engine_;
};

}  // namespace springfit
