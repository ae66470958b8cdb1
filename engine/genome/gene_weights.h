// Summaries of per-gene weights (a model's stiffness per candidate, 0 = absent), which the
// fits, the probe objective and a problem's training stiffness share.
#pragma once

#include <algorithm>
#include <vector>

namespace springfit {

// The springs present (weight > 0).
inline int PresentSprings(const std::vector<double>& weights) {
  return static_cast<int>(
      std::count_if(weights.begin(), weights.end(), [](double w) { return w > 0.0; }));
}

// The median of the positive weights (the upper one of an even count; 1 when there is none).
inline double MedianPositive(const std::vector<double>& weights) {
  std::vector<double> positive;
  for (const double w : weights) {
    if (w > 0.0) positive.push_back(w);
  }
  if (positive.empty()) return 1.0;
  const auto mid = positive.begin() + static_cast<std::ptrdiff_t>(positive.size() / 2);
  std::nth_element(positive.begin(), mid, positive.end());
  return *mid;
}

}  // namespace springfit
