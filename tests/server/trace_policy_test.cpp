// Which rows of a job's trace the store keeps (server/jobs/trace_policy.h): every generation below
// 10,000, then every 10th, 100th, ... per decade, the stride growing no further than 100,000
// (from 100,000,000 on, up to INT_MAX); a row that improved the best, and the last row, always.
#include "server/jobs/trace_policy.h"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <set>

#include <gtest/gtest.h>

namespace springfit::server {
namespace {

// The rule restated decade by decade: the stride a row that neither improved nor was last
// must be a multiple of.
int Stride(int generation) {
  if (generation < 10000) return 1;
  if (generation < 100000) return 10;
  if (generation < 1000000) return 100;
  if (generation < 10000000) return 1000;
  if (generation < 100000000) return 10000;
  return 100000;  // 1e8 and beyond, 1e9 and INT_MAX included: the stride stops growing
}

TEST(TracePolicy, EveryGenerationBelowTenThousandIsKept) {
  int dropped = 0;
  int first = -1;
  for (int g = 0; g < 10000; ++g) {
    if (!KeepTraceRow(g, false, false)) {
      if (first < 0) first = g;
      ++dropped;
    }
  }
  EXPECT_EQ(dropped, 0) << "first dropped: " << first;
}

TEST(TracePolicy, TheStrideGrowsTenfoldPerDecadeUpToOneHundredThousand) {
  // Multiples of their decade's stride (10 from 10^4, 100 from 10^5, ..., 100,000 from 10^8).
  // Beyond 10^8 the stride stays 100,000: 10^9 starts no new decade of the rule (a stride of
  // 1,000,000 would drop 1,000,100,000 and 1,000,500,000).
  const int kept[] = {9999,      10000,      10010,      99990,      100000,
                      100100,    999900,     1000000,    1001000,    9999000,
                      10000000,  10010000,   99990000,   100000000,  100100000,
                      999900000, 1000000000, 1000100000, 1000500000, 2147400000};
  // Not multiples of their decade's stride, INT_MAX included (the rule must end there).
  constexpr int kIntMax = std::numeric_limits<int>::max();
  const int dropped[] = {10001,     10005,     10009,      99999,      100010,   100050,
                         999990,    1000100,   9999900,    10001000,   99999000, 100010000,
                         100050000, 999990000, 1000010000, 2147483600, kIntMax};
  for (const int g : kept) EXPECT_TRUE(KeepTraceRow(g, false, false)) << "generation " << g;
  for (const int g : dropped) EXPECT_FALSE(KeepTraceRow(g, false, false)) << "generation " << g;
  // An improvement or the last row is kept whatever its generation.
  for (const int g : dropped) {
    EXPECT_TRUE(KeepTraceRow(g, true, false)) << "improved " << g;
    EXPECT_TRUE(KeepTraceRow(g, false, true)) << "last " << g;
    EXPECT_TRUE(KeepTraceRow(g, true, true)) << "improved and last " << g;
  }
}

TEST(TracePolicy, MatchesThePerDecadeRuleAroundEveryBoundaryAndUpToIntMax) {
  const std::int64_t int_max = std::numeric_limits<int>::max();
  const std::int64_t centres[] = {10000, 100000, 1000000, 10000000, 100000000, 1000000000, int_max};
  for (const std::int64_t centre : centres) {
    const std::int64_t lo = std::max<std::int64_t>(0, centre - 200000);
    const std::int64_t hi = std::min<std::int64_t>(int_max, centre + 200000);
    int mismatches = 0;
    std::int64_t first = -1;
    for (std::int64_t g64 = lo; g64 <= hi; ++g64) {
      const int g = static_cast<int>(g64);
      if (KeepTraceRow(g, false, false) != (g % Stride(g) == 0)) {
        if (first < 0) first = g64;
        ++mismatches;
      }
    }
    EXPECT_EQ(mismatches, 0) << "around " << centre << ", first at " << first;
  }
}

TEST(TracePolicy, ALongJobKeepsABoundedNumberOfRows) {
  // Generations 0..2,000,000, the last one final, no improvement: 10,000 rows below 10^4,
  // 9,000 in [10^4, 10^5) (every 10th), 9,000 in [10^5, 10^6) (every 100th), and the 1,001
  // multiples of 1,000 in [10^6, 2*10^6].
  constexpr int kLast = 2000000;
  constexpr int kExpected = 10000 + 9000 + 9000 + 1001;
  int kept = 0;
  for (int g = 0; g <= kLast; ++g) {
    if (KeepTraceRow(g, false, g == kLast)) ++kept;
  }
  EXPECT_EQ(kept, kExpected);

  // Improvements at generations the stride would drop add exactly their own rows; one at the
  // last generation (a multiple of 1,000, kept anyway) adds none.
  const std::set<int> improved = {10001, 123457, 1500001, kLast};
  kept = 0;
  for (int g = 0; g <= kLast; ++g) {
    if (KeepTraceRow(g, improved.contains(g), g == kLast)) ++kept;
  }
  EXPECT_EQ(kept, kExpected + 3);

  // A whole decade further on stores 9,000 rows, not 9,000,000.
  kept = 0;
  for (int g = 1000000; g < 10000000; ++g) {
    if (KeepTraceRow(g, false, false)) ++kept;
  }
  EXPECT_EQ(kept, 9000);
}

}  // namespace
}  // namespace springfit::server
