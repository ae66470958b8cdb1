#include "server/log_format.h"

#include <memory>
#include <string>
#include <thread>

#include <gtest/gtest.h>
#include <spdlog/sinks/null_sink.h>
#include <spdlog/spdlog.h>

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

// The process ends at once (jobs that outlast the shutdown's wait, a second signal) while other
// threads may still log: after the log is flushed for the exit, logging works from any thread,
// and the exit code comes out (spdlog::shutdown() before _Exit freed the logger under them: a
// SIGSEGV instead; issue 48, item 5).
TEST(LogFormatDeathTest, LoggingAfterTheExitFlushStillWorks) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        spdlog::set_default_logger(std::make_shared<spdlog::logger>(
            "null", std::make_shared<spdlog::sinks::null_sink_mt>()));
        FlushLogForExit();
        std::thread late([] { spdlog::info("job 7 interrupted"); });
        late.join();
        spdlog::warn("still logging");
        FlushLogAndExit(3);
      },
      ::testing::ExitedWithCode(3), "");
}

}  // namespace
}  // namespace springfit::server
