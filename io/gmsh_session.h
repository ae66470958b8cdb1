// The Gmsh library's global state for the length of one read or write: initialised quietly
// (no terminal output, no configuration files), finalised on every exit, one at a time.
#pragma once

#include <gmsh.h>

#include <mutex>
#include <stdexcept>
#include <string>

#include "engine/api/input_error.h"

namespace springfit::io {

class GmshSession {
 public:
  GmshSession() : lock_(Mutex()) {
    gmsh::initialize(0, nullptr, false);
    gmsh::option::setNumber("General.Terminal", 0);
    gmsh::option::setNumber("General.Verbosity", 1);  // errors only, and they throw
  }
  ~GmshSession() { gmsh::finalize(); }
  GmshSession(const GmshSession&) = delete;
  GmshSession& operator=(const GmshSession&) = delete;

 private:
  static std::mutex& Mutex() {
    static std::mutex mutex;
    return mutex;
  }
  std::lock_guard<std::mutex> lock_;
};

// Gmsh reports errors by throwing (an std::exception, or its last error as a string).
template <typename F>
inline void GmshCall(const std::string& path, const char* what, F&& call) {
  try {
    call();
  } catch (const std::exception& e) {
    throw InputError("", path + ": " + what + ": " + e.what());
  } catch (const std::string& e) {
    throw InputError("", path + ": " + what + ": " + e);
  } catch (...) {
    throw InputError("", path + ": " + what + " failed (Gmsh)");
  }
}

}  // namespace springfit::io
