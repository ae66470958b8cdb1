// Text for XML files (the SVG figures, VTK XML, SOFA scenes), which carry users' names.
#pragma once

#include <string>
#include <string_view>

namespace springfit::io {

// Escapes &, <, >, " for text and attribute values; control characters XML 1.0 forbids and
// invalid UTF-8 become U+FFFD.
std::string XmlEscape(std::string_view text);

// Text for inside an XML comment: escaped, and no "--" (which would end it).
std::string XmlCommentText(std::string_view text);

}  // namespace springfit::io
