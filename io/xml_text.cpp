#include "io/xml_text.h"

namespace springfit::io {

std::string XmlEscape(std::string_view text) {
  // XML 1.0 allows no control characters but tab, LF and CR, even as references, and the
  // document says it is UTF-8: anything else becomes U+FFFD. Names come from users' scenes.
  constexpr std::string_view kReplacement = "\xEF\xBF\xBD";
  std::string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x80) {
      switch (c) {
        case '&':
          out += "&amp;";
          break;
        case '<':
          out += "&lt;";
          break;
        case '>':
          out += "&gt;";
          break;
        case '"':
          out += "&quot;";
          break;
        default:
          (c < 0x20 && c != '\t' && c != '\n' && c != '\r') ? out += kReplacement
                                                            : out += static_cast<char>(c);
      }
      ++i;
      continue;
    }
    // A multi-byte sequence: its length from the lead byte, then continuation bytes; overlong
    // forms, surrogates and code points above U+10FFFF are refused.
    const int length = c >= 0xC2 && c <= 0xDF   ? 2
                       : c >= 0xE0 && c <= 0xEF ? 3
                       : c >= 0xF0 && c <= 0xF4 ? 4
                                                : 0;
    bool valid = length > 0 && i + static_cast<std::size_t>(length) <= text.size();
    for (int k = 1; valid && k < length; ++k)
      valid = (static_cast<unsigned char>(text[i + k]) & 0xC0) == 0x80;
    if (valid && length >= 3) {
      const auto second = static_cast<unsigned char>(text[i + 1]);
      if (c == 0xE0) valid = second >= 0xA0;
      if (c == 0xED) valid = second < 0xA0;
      if (c == 0xF0) valid = second >= 0x90;
      if (c == 0xF4) valid = second < 0x90;
    }
    if (valid) {
      out.append(text.substr(i, static_cast<std::size_t>(length)));
      i += static_cast<std::size_t>(length);
    } else {
      out += kReplacement;
      ++i;
    }
  }
  return out;
}

std::string XmlCommentText(std::string_view text) {
  std::string out = XmlEscape(text);
  for (std::size_t at = out.find("--"); at != std::string::npos; at = out.find("--", at))
    out.replace(at, 2, "- -");
  return out;
}

}  // namespace springfit::io
