// Splits a byte stream into JSON messages at JSON value boundaries (proto/RPC.md, "Framing").
//
// Clients may send one message per line, or a bare JSON value with no newline and wait for
// the answer (what many JSON-RPC libraries' TCP transports do); pretty-printed messages that
// span lines work too. So the framer does not look for newlines: it follows the JSON grammar
// byte by byte and cuts a message where its top-level object or array closes.
//
// Following the grammar also finds malformed input as soon as it goes wrong (`{{`, a stray
// word, a raw control character in a string), without waiting for a closing bracket that
// may never come. The bytes up to the next newline are then dropped, and framing resumes
// there: a garbage line costs one error, not the connection.
//
// Bounds: a message longer than `max_message_bytes` ends the stream (the caller answers and
// closes: there is no telling where an over-long message would end), and nesting deeper than
// `max_depth` is malformed (deep nesting is how one crashes recursive parsers).
#pragma once
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace springfit::proto {

class JsonFramer {
 public:
  struct Options {
    std::size_t max_message_bytes = std::size_t{16} << 20;  // 16 MiB: a scene of ~100k nodes
    int max_depth = 64;  // scenes nest 4 deep, JSON-RPC batches add 1
  };

  struct Frame {
    enum class Kind {
      kMessage,    // `text` is one complete JSON object or array (UTF-8 not yet checked)
      kMalformed,  // `error` says what and where; the rest of its line was dropped
      kTooLarge,   // over max_message_bytes: the stream cannot be resynchronised
    };
    Kind kind = Kind::kMessage;
    std::string text;
    std::string error;
  };

  JsonFramer() : JsonFramer(Options{}) {}
  explicit JsonFramer(Options options) : options_(options) {}
  // A new bound for the messages framed from now on (the daemon raises it once a connection
  // has authenticated).
  void set_max_message_bytes(std::size_t bytes) { options_.max_message_bytes = bytes; }
  std::size_t max_message_bytes() const { return options_.max_message_bytes; }

  // Scans `bytes` and returns the frames they complete, in order. Bytes of an unfinished
  // message are kept for the next call. After kTooLarge, everything is ignored.
  std::vector<Frame> Feed(std::string_view bytes);

  // Bytes held for an unfinished message.
  std::size_t pending_bytes() const { return message_.size(); }
  // True between messages (nothing pending): an idle connection may be closed here cleanly.
  bool at_boundary() const { return state_ == State::kTop && message_.empty(); }

 private:
  enum class State {
    kTop,          // between messages: whitespace, then '{' or '['
    kValue,        // a value is required (after ':' or ',' in an array)
    kArrayFirst,   // after '[': a value or ']'
    kObjectFirst,  // after '{': a key or '}'
    kObjectKey,    // after ',' in an object: a key
    kColon,        // after a key
    kAfterValue,   // ',' or the container's closing bracket
    kString,
    kStringEscape,
    kStringUnicode,
    kNumber,
    kLiteral,
    kSkipLine,  // dropping a malformed line
    kClosed,    // after kTooLarge
  };
  // Number grammar positions: -?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)?
  enum class NumberPart {
    kSign,
    kZero,
    kInteger,
    kFractionStart,
    kFraction,
    kExponentStart,
    kExponentSign,
    kExponent
  };

  // Returns false when `c` breaks the grammar (error_ is set).
  bool Step(char c);
  bool StartValue(char c);
  bool EndNumber(char c);  // `c` follows a finished number
  void CloseValue();       // a value ended: back to the container, or a message is complete
  bool Fail(std::string what);

  Options options_;
  State state_ = State::kTop;
  std::vector<char> stack_;  // open containers, '{' or '['
  bool string_is_key_ = false;
  int unicode_digits_ = 0;
  NumberPart number_ = NumberPart::kSign;
  std::string_view literal_;  // the literal being matched ("true", "false", "null")
  std::size_t literal_pos_ = 0;
  std::string message_;    // bytes of the current message
  bool complete_ = false;  // message_ holds a whole message
  std::string error_;
  std::size_t offset_ = 0;  // bytes of the stream scanned so far, for messages
};

}  // namespace springfit::proto
