#include "proto/json_framer.h"

#include <gtest/gtest.h>

namespace springfit::proto {
namespace {

using Kind = JsonFramer::Frame::Kind;

std::vector<std::string> Messages(const std::vector<JsonFramer::Frame>& frames) {
  std::vector<std::string> out;
  for (const auto& f : frames)
    out.push_back(f.kind == Kind::kMessage ? f.text : "<" + f.error + ">");
  return out;
}

TEST(JsonFramer, OneMessagePerLine) {
  JsonFramer f;
  EXPECT_EQ(Messages(f.Feed("{\"a\":1}\n[1,2]\n")),
            (std::vector<std::string>{"{\"a\":1}", "[1,2]"}));
  EXPECT_TRUE(f.at_boundary());
}

TEST(JsonFramer, BareMessageWithoutNewlineIsCompleteAtItsClosingBracket) {
  JsonFramer f;
  const auto frames = f.Feed("{\"id\":1,\"method\":\"server.info\"}");
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0].kind, Kind::kMessage);
}

TEST(JsonFramer, PrettyPrintedMessagesAndBackToBackMessages) {
  JsonFramer f;
  const auto frames = f.Feed("{\n  \"a\": [\n    1,\n    2\n  ]\n}{\"b\":true}[]  \r\n\t{}");
  EXPECT_EQ(Messages(frames), (std::vector<std::string>{"{\n  \"a\": [\n    1,\n    2\n  ]\n}",
                                                        "{\"b\":true}", "[]", "{}"}));
}

TEST(JsonFramer, ByteByByteGivesTheSameMessages) {
  const std::string text =
      R"({"s":"a}]\"\\\u00e9{[","n":[-0.5e+3,0,12E-2,true,false,null,{}]} [{"x":{"y":[]}}])";
  JsonFramer whole;
  const auto expected = Messages(whole.Feed(text));
  ASSERT_EQ(expected.size(), 2u);
  JsonFramer split;
  std::vector<JsonFramer::Frame> frames;
  for (char c : text) {
    for (auto& fr : split.Feed(std::string_view(&c, 1))) frames.push_back(std::move(fr));
  }
  EXPECT_EQ(Messages(frames), expected);
}

TEST(JsonFramer, GarbageIsReportedAndTheNextLineIsRead) {
  JsonFramer f;
  const auto frames = f.Feed("hello world\n{{\"a\":1}\n{\"ok\":1}\n");
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].kind, Kind::kMalformed);
  EXPECT_NE(frames[0].error.find("'h'"), std::string::npos) << frames[0].error;
  EXPECT_EQ(frames[1].kind, Kind::kMalformed);
  EXPECT_NE(frames[1].error.find("where a key was expected"), std::string::npos) << frames[1].error;
  EXPECT_EQ(frames[2].kind, Kind::kMessage);
  EXPECT_EQ(frames[2].text, "{\"ok\":1}");
}

TEST(JsonFramer, GrammarErrorsInsideAMessage) {
  for (const char* bad :
       {"{\"a\" 1}\n", "{\"a\":01}\n", "[1,]\n", "{\"a\":tru}\n", "[\"\\x\"]\n", "[1.]\n", "[-]\n",
        "[1e]\n", "{\"a\":1,}\n", "[\"\\u12g4\"]\n", "[1 2]\n", "{]\n", "[}\n"}) {
    JsonFramer f;
    const auto frames = f.Feed(bad);
    ASSERT_EQ(frames.size(), 1u) << bad;
    EXPECT_EQ(frames[0].kind, Kind::kMalformed) << bad;
    EXPECT_EQ(f.Feed("{}").size(), 1u) << "resynchronised after " << bad;
  }
}

TEST(JsonFramer, RawControlCharacterInAStringIsMalformedAndTheLineEndsThere) {
  JsonFramer f;
  // The raw newline inside the string is the error; framing resumes right after it.
  const auto frames = f.Feed("{\"a\":\"x\n{\"b\":2}\n");
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].kind, Kind::kMalformed);
  EXPECT_EQ(frames[1].text, "{\"b\":2}");
}

TEST(JsonFramer, DeepNestingIsMalformed) {
  JsonFramer f(JsonFramer::Options{1 << 20, 8});
  EXPECT_EQ(f.Feed(std::string(8, '[') + std::string(8, ']')).at(0).kind, Kind::kMessage);
  const auto frames = f.Feed(std::string(9, '[') + "\n{}");
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].kind, Kind::kMalformed);
  EXPECT_NE(frames[0].error.find("nesting deeper than 8"), std::string::npos);
  EXPECT_EQ(frames[1].kind, Kind::kMessage);
}

TEST(JsonFramer, TooLargeEndsTheStream) {
  JsonFramer f(JsonFramer::Options{16, 64});
  EXPECT_EQ(f.Feed("{\"a\":\"0123456\"}").at(0).kind, Kind::kMessage);  // 15 bytes
  const auto frames = f.Feed("{\"a\":\"0123456789\"}{}");
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0].kind, Kind::kTooLarge);
  EXPECT_TRUE(f.Feed("{}").empty());
}

TEST(JsonFramer, TheLimitIsInclusive) {
  const std::string at_limit = "{\"a\":\"01234567\"}";  // 16 bytes
  ASSERT_EQ(at_limit.size(), 16u);
  JsonFramer exact(JsonFramer::Options{16, 64});
  EXPECT_EQ(exact.Feed(at_limit).at(0).kind, Kind::kMessage);
  // One byte more, completing on that byte: too large, not a message.
  JsonFramer over(JsonFramer::Options{16, 64});
  const auto frames = over.Feed("{\"a\":\"012345678\"}");
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0].kind, Kind::kTooLarge);
}

TEST(JsonFramer, UnfinishedMessageIsHeld) {
  JsonFramer f;
  EXPECT_TRUE(f.Feed("{\"a\": [1, 2").empty());
  EXPECT_FALSE(f.at_boundary());
  EXPECT_GT(f.pending_bytes(), 0u);
  const auto frames = f.Feed("]}");
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0].text, "{\"a\": [1, 2]}");
}

}  // namespace
}  // namespace springfit::proto
