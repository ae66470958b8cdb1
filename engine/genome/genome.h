// A topology over a problem's genes: one bit per gene, 1 = the candidate spring is present
// (engine/problem/problem.h lays the genes out).
#pragma once

#include <cstdint>
#include <vector>

namespace springfit {

using Genome = std::vector<std::uint8_t>;

}  // namespace springfit
