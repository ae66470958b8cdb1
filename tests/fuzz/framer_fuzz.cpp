// libFuzzer target for the JSON message framer (proto/json_framer.h).
//
// Beyond "no crash, no sanitizer report", it checks what the daemon relies on:
//  - framing does not depend on how TCP splits the stream: the input fed whole and fed in
//    chunks (sizes taken from the input itself) gives the same frames;
//  - a message frame is one JSON object or array, and parses as JSON when its bytes are
//    valid UTF-8 (the framer leaves UTF-8 to the parser);
//  - a message frame respects the size limit;
//  - and the other way round: a stream that is one JSON object or array, well inside the
//    size and depth limits, comes out as exactly that one message.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "proto/json_framer.h"

namespace {

using springfit::proto::JsonFramer;

// Small limits so that the fuzzer reaches the size and depth bounds with short inputs.
JsonFramer::Options FuzzOptions() {
  JsonFramer::Options options;
  options.max_message_bytes = 512;
  options.max_depth = 8;
  return options;
}

bool SameFrames(const std::vector<JsonFramer::Frame>& a, const std::vector<JsonFramer::Frame>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a[i].kind != b[i].kind || a[i].text != b[i].text || a[i].error != b[i].error) return false;
  }
  return true;
}

void Check(bool condition) {
  if (!condition) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  // The first byte chooses the chunk size of the split feed; the rest is the stream.
  const std::size_t chunk = 1 + data[0] % 17;
  const std::string_view stream(reinterpret_cast<const char*>(data + 1), size - 1);

  JsonFramer whole(FuzzOptions());
  const auto frames = whole.Feed(stream);

  JsonFramer split(FuzzOptions());
  std::vector<JsonFramer::Frame> split_frames;
  for (std::size_t at = 0; at < stream.size(); at += chunk) {
    for (auto& frame : split.Feed(stream.substr(at, chunk)))
      split_frames.push_back(std::move(frame));
  }
  Check(SameFrames(frames, split_frames));
  Check(whole.pending_bytes() == split.pending_bytes());

  for (const auto& frame : frames) {
    if (frame.kind != JsonFramer::Frame::Kind::kMessage) continue;
    Check(frame.text.size() <= FuzzOptions().max_message_bytes);
    Check(!frame.text.empty());
    const char open = frame.text.front();
    Check(open == '{' || open == '[');
    // The framer checks the grammar only: the parser may still refuse invalid UTF-8 or an
    // unpaired \uD800-\uDFFF escape in a string, or a number beyond the double range (all
    // answered -32700 by the daemon). Any other parse failure means the framer cut a message
    // wrongly.
    try {
      (void)nlohmann::json::parse(frame.text);
    } catch (const nlohmann::json::parse_error& e) {
      const std::string_view what = e.what();
      Check(e.id == 101 && (what.find("invalid string: ill-formed UTF-8") != what.npos ||
                            what.find("invalid string: surrogate") != what.npos));
    } catch (const nlohmann::json::out_of_range& e) {
      Check(e.id == 406);  // number overflow
    }
  }

  // The reverse: a single valid object or array must be framed as one message.
  const std::size_t first = stream.find_first_not_of(" \t\r\n");
  if (first == std::string_view::npos || (stream[first] != '{' && stream[first] != '[')) return 0;
  const std::size_t last = stream.find_last_not_of(" \t\r\n");
  const std::string_view value = stream.substr(first, last - first + 1);
  // nlohmann's parser takes a NUL byte for the end of its input: no reference there.
  if (value.size() > FuzzOptions().max_message_bytes || value.find('\0') != value.npos) return 0;
  int depth = 0;
  bool valid = true;
  try {
    // Iterators, not the view itself: a string_view could be read as a C string, up to a NUL.
    (void)nlohmann::json::parse(value.begin(), value.end(),
                                [&](int d, nlohmann::json::parse_event_t, nlohmann::json&) {
                                  depth = std::max(depth, d);
                                  return true;
                                });
  } catch (const nlohmann::json::exception&) {
    valid = false;
  }
  // Two levels of margin below the framer's depth limit, so that the two depth counts need
  // not agree on where nesting starts.
  if (!valid || depth > FuzzOptions().max_depth - 2) return 0;
  Check(frames.size() == 1 && frames[0].kind == JsonFramer::Frame::Kind::kMessage &&
        frames[0].text == value);
  return 0;
}
