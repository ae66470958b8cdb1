#include "proto/json_framer.h"

#include <fmt/format.h>

namespace springfit::proto {
namespace {

bool IsSpace(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r';
}
bool IsDigit(char c) {
  return c >= '0' && c <= '9';
}
bool IsHexDigit(char c) {
  return IsDigit(c) || (c >= 'a' && c <= 'f') || (c >= 'A' && c <= 'F');
}

// A byte as it can be shown in a message: 'x', or \xNN when not printable.
std::string Shown(char c) {
  const auto u = static_cast<unsigned char>(c);
  return u >= 0x20 && u < 0x7f ? fmt::format("'{}'", c) : fmt::format("byte 0x{:02x}", u);
}

}  // namespace

std::vector<JsonFramer::Frame> JsonFramer::Feed(std::string_view bytes) {
  std::vector<Frame> frames;
  for (const char c : bytes) {
    ++offset_;
    if (state_ == State::kClosed) break;
    if (state_ == State::kSkipLine) {
      if (c == '\n') state_ = State::kTop;
      continue;
    }
    if (state_ == State::kTop && IsSpace(c)) continue;
    message_.push_back(c);
    if (!Step(c)) {
      frames.push_back({Frame::Kind::kMalformed, {}, error_});
      message_.clear();
      stack_.clear();
      state_ = c == '\n' ? State::kTop : State::kSkipLine;
      continue;
    }
    // The size first: a message that completes one byte over the limit is still too large.
    if (message_.size() > options_.max_message_bytes) {
      frames.push_back(
          {Frame::Kind::kTooLarge,
           {},
           "message longer than " + std::to_string(options_.max_message_bytes) + " bytes"});
      message_.clear();
      message_.shrink_to_fit();
      stack_.clear();
      state_ = State::kClosed;
    } else if (complete_) {
      frames.push_back({Frame::Kind::kMessage, std::move(message_), {}});
      message_.clear();
      complete_ = false;
    }
  }
  return frames;
}

bool JsonFramer::Fail(std::string what) {
  error_ = std::move(what) + " at byte " + std::to_string(message_.size()) + " of the message";
  return false;
}

void JsonFramer::CloseValue() {
  if (stack_.empty()) {
    complete_ = true;
    state_ = State::kTop;
  } else {
    state_ = State::kAfterValue;
  }
}

bool JsonFramer::StartValue(char c) {
  switch (c) {
    case '{':
    case '[':
      if (static_cast<int>(stack_.size()) >= options_.max_depth) {
        return Fail("nesting deeper than " + std::to_string(options_.max_depth) + " levels");
      }
      stack_.push_back(c);
      state_ = c == '{' ? State::kObjectFirst : State::kArrayFirst;
      return true;
    case '"':
      string_is_key_ = false;
      state_ = State::kString;
      return true;
    case '-':
      number_ = NumberPart::kSign;
      state_ = State::kNumber;
      return true;
    case 't':
    case 'f':
    case 'n':
      literal_ = c == 't' ? "true" : c == 'f' ? "false" : "null";
      literal_pos_ = 1;
      state_ = State::kLiteral;
      return true;
    default:
      if (IsDigit(c)) {
        number_ = c == '0' ? NumberPart::kZero : NumberPart::kInteger;
        state_ = State::kNumber;
        return true;
      }
      return Fail("unexpected " + Shown(c) + " where a value was expected");
  }
}

bool JsonFramer::EndNumber(char c) {
  CloseValue();
  return Step(c);
}

bool JsonFramer::Step(char c) {
  switch (state_) {
    case State::kTop:
      if (c == '{' || c == '[') return StartValue(c);
      return Fail("unexpected " + Shown(c) + ": a message is a JSON object or array");
    case State::kValue:
      return IsSpace(c) || StartValue(c);
    case State::kArrayFirst:
      if (IsSpace(c)) return true;
      if (c == ']') {
        stack_.pop_back();
        CloseValue();
        return true;
      }
      return StartValue(c);
    case State::kObjectFirst:
    case State::kObjectKey:
      if (IsSpace(c)) return true;
      if (c == '"') {
        string_is_key_ = true;
        state_ = State::kString;
        return true;
      }
      if (c == '}' && state_ == State::kObjectFirst) {
        stack_.pop_back();
        CloseValue();
        return true;
      }
      return Fail("unexpected " + Shown(c) + " where a key was expected");
    case State::kColon:
      if (IsSpace(c)) return true;
      if (c == ':') {
        state_ = State::kValue;
        return true;
      }
      return Fail("unexpected " + Shown(c) + " where ':' was expected");
    case State::kAfterValue:
      if (IsSpace(c)) return true;
      if (c == ',') {
        state_ = stack_.back() == '{' ? State::kObjectKey : State::kValue;
        return true;
      }
      if ((c == '}' && stack_.back() == '{') || (c == ']' && stack_.back() == '[')) {
        stack_.pop_back();
        CloseValue();
        return true;
      }
      return Fail("unexpected " + Shown(c) + " where ',' or '" +
                  (stack_.back() == '{' ? "}" : "]") + "' was expected");
    case State::kString:
      if (c == '"') {
        if (string_is_key_) {
          state_ = State::kColon;
        } else {
          CloseValue();
        }
        return true;
      }
      if (c == '\\') {
        state_ = State::kStringEscape;
        return true;
      }
      if (static_cast<unsigned char>(c) < 0x20)
        return Fail("unescaped control character (" + Shown(c) + ") in a string");
      return true;
    case State::kStringEscape:
      if (c == 'u') {
        unicode_digits_ = 4;
        state_ = State::kStringUnicode;
        return true;
      }
      if (c == '"' || c == '\\' || c == '/' || c == 'b' || c == 'f' || c == 'n' || c == 'r' ||
          c == 't') {
        state_ = State::kString;
        return true;
      }
      return Fail("invalid escape \\" + std::string(1, c) + " in a string");
    case State::kStringUnicode:
      if (!IsHexDigit(c)) return Fail("invalid \\u escape in a string");
      if (--unicode_digits_ == 0) state_ = State::kString;
      return true;
    case State::kNumber:
      switch (number_) {
        case NumberPart::kSign:
          if (c == '0') {
            number_ = NumberPart::kZero;
            return true;
          }
          if (IsDigit(c)) {
            number_ = NumberPart::kInteger;
            return true;
          }
          return Fail("invalid number");
        case NumberPart::kZero:
        case NumberPart::kInteger:
          if (IsDigit(c) && number_ == NumberPart::kInteger) return true;
          if (IsDigit(c)) return Fail("invalid number (leading zero)");
          if (c == '.') {
            number_ = NumberPart::kFractionStart;
            return true;
          }
          if (c == 'e' || c == 'E') {
            number_ = NumberPart::kExponentStart;
            return true;
          }
          return EndNumber(c);
        case NumberPart::kFractionStart:
          if (!IsDigit(c)) return Fail("invalid number");
          number_ = NumberPart::kFraction;
          return true;
        case NumberPart::kFraction:
          if (IsDigit(c)) return true;
          if (c == 'e' || c == 'E') {
            number_ = NumberPart::kExponentStart;
            return true;
          }
          return EndNumber(c);
        case NumberPart::kExponentStart:
          if (c == '+' || c == '-') {
            number_ = NumberPart::kExponentSign;
            return true;
          }
          [[fallthrough]];
        case NumberPart::kExponentSign:
          if (!IsDigit(c)) return Fail("invalid number");
          number_ = NumberPart::kExponent;
          return true;
        case NumberPart::kExponent:
          if (IsDigit(c)) return true;
          return EndNumber(c);
      }
      return false;
    case State::kLiteral:
      if (c != literal_[literal_pos_])
        return Fail("invalid literal (expected " + std::string(literal_) + ")");
      if (++literal_pos_ == literal_.size()) CloseValue();
      return true;
    case State::kSkipLine:
    case State::kClosed:
      return true;
  }
  return false;
}

}  // namespace springfit::proto
