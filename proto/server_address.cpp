#include "proto/server_address.h"

#include <charconv>

#include "engine/api/input_error.h"

namespace springfit::proto {

ServerAddress ParseServerAddress(const std::string& text, const std::string& what) {
  const auto colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == text.size()) {
    throw InputError(what, "expected HOST:PORT, got '" + text + "'");
  }
  ServerAddress a;
  a.host = text.substr(0, colon);
  if (a.host.size() >= 2 && a.host.front() == '[' && a.host.back() == ']')
    a.host = a.host.substr(1, a.host.size() - 2);
  const std::string port = text.substr(colon + 1);
  unsigned value = 0;
  const auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), value);
  if (ec != std::errc() || end != port.data() + port.size() || value > 65535) {
    throw InputError(what, "port '" + port + "' is not a number in [0, 65535]");
  }
  a.port = static_cast<unsigned short>(value);
  return a;
}

}  // namespace springfit::proto
