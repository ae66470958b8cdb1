// Wall time for progress, phase timings and stores' metrics (never for results: they do not
// depend on time).
#pragma once

#include <chrono>

namespace springfit {

// Seconds of wall time since `start`.
inline double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Seconds since `lap`, and `lap` moved to now (one reading of the clock): consecutive laps add
// up to the whole.
inline double NextLap(std::chrono::steady_clock::time_point& lap) {
  const auto now = std::chrono::steady_clock::now();
  const double seconds = std::chrono::duration<double>(now - lap).count();
  lap = now;
  return seconds;
}

}  // namespace springfit
