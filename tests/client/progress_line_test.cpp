// The progress line's pieces: durations for people, lines cut to a terminal's width.
#include "client/progress_line.h"

#include <gtest/gtest.h>

namespace springfit::cli {
namespace {

TEST(ProgressLine, ClockTextIsMinutesOrHours) {
  EXPECT_EQ(ClockText(0.0), "0:00");
  EXPECT_EQ(ClockText(7.4), "0:07");
  EXPECT_EQ(ClockText(754.0), "12:34");
  EXPECT_EQ(ClockText(3599.4), "59:59");
  EXPECT_EQ(ClockText(3723.0), "1:02:03");
  EXPECT_EQ(ClockText(100.0 * 3600.0), "100:00:00");
  EXPECT_EQ(ClockText(-1.0), "-");
  EXPECT_EQ(ClockText(1.0 / 0.0), "-");
}

TEST(ProgressLine, LinesAreCutToTheTerminalsWidth) {
  const std::string line =
      "gen 212/1000  error 0.012  missing 5 extra 4  0:04  ETA <= 0:15  9800 eval/s  cost 0.0031";
  EXPECT_EQ(FitToWidth(line, 200), line);
  // The last column stays free: a character there moves the cursor to the next row.
  EXPECT_EQ(FitToWidth(line, static_cast<int>(line.size()) + 1), line);
  const std::string cut = FitToWidth(line, 40);
  EXPECT_EQ(cut.size(), 39u);
  EXPECT_EQ(cut, line.substr(0, 36) + "...");
  EXPECT_LE(FitToWidth(line, 80).size(), 79u);
  EXPECT_EQ(FitToWidth(line, 2), "...");
}

}  // namespace
}  // namespace springfit::cli
