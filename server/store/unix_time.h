// Wall-clock time as the store and the wire carry it: seconds since the Unix epoch.
#pragma once
#include <chrono>

namespace springfit::server {

inline double UnixNow() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

}  // namespace springfit::server
