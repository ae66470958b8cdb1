// The Gmsh library's global state for the length of one read or write: initialised quietly
// (no terminal output, no configuration files), finalised on every exit, one at a time.
#pragma once

#include <gmsh.h>

#include <mutex>

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

}  // namespace springfit::io
