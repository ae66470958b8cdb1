// The one exception type for bad input: a scene, a topology or an option that breaks a rule.
//
// `path` names the offending field as a JSON path into the scene (e.g.
// "load_cases[2].forces[0].node"); what() is "path: message". Thrown only while building or
// validating (proto/ codecs, Problem::Build), never from the solver or the search loops, whose
// expected failures (a mechanism, no convergence) are data in their summaries.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>

namespace springfit {

class InputError : public std::runtime_error {
 public:
  InputError(std::string path, const std::string& message)
      : std::runtime_error(path.empty() ? message : path + ": " + message),
        path_(std::move(path)) {}
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// The path of the scene's load case k, as errors and messages name it.
inline std::string LoadCasePath(std::size_t k) {
  return "load_cases[" + std::to_string(k) + "]";
}

}  // namespace springfit
