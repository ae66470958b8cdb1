#include "server/log_format.h"

#include <string>

#include <gtest/gtest.h>

namespace springfit::server {
namespace {

TEST(LogFormat, ControlCharactersCannotForgeALine) {
  EXPECT_EQ(EscapeLogText("label\ncritical FORGED: token accepted"),
            "label\\ncritical FORGED: token accepted");
  EXPECT_EQ(EscapeLogText("a\rb\tc\\d\x01\x7f"), "a\\rb\\tc\\\\d\\x01\\x7f");
  EXPECT_EQ(EscapeLogText("ünïcode stays"), "ünïcode stays");
}

TEST(LogFormat, LongTextIsCut) {
  const std::string name(10 << 20, 'x');
  const std::string logged = EscapeLogText(name);
  EXPECT_LT(logged.size(), kMaxLogMessageBytes + 40);
  EXPECT_NE(logged.find("... (10485760 bytes)"), std::string::npos);
  EXPECT_EQ(EscapeLogText("short", 3), "sho... (5 bytes)");
}

}  // namespace
}  // namespace springfit::server
