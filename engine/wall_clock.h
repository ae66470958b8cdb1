// Wall time for progress, phase timings and stores' metrics (never for results: they do not
// depend on time).
#pragma once

#include <chrono>

namespace springfit {

// Seconds of wall time since `start`.
inline double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace springfit
