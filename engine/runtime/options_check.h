// The one form of an Options struct's Validate() failure: the struct, the field, the value and
// the rule it breaks, e.g.
//   DirectOptions::significance = -1. Violated constraint: value >= 0
// Validate() runs at the entry of the algorithm the options configure, before any work.
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>

namespace springfit {

class OptionsCheck {
 public:
  explicit OptionsCheck(std::string_view owner) : owner_(owner) {}
  // Throws std::invalid_argument unless `ok`.
  void Require(bool ok, std::string_view field, double value, std::string_view rule) const {
    if (!ok) Fail(field, value, rule);
  }
  // A nested Options struct's field name, for its own check ("DirectOptions::nnls").
  std::string Nested(std::string_view field) const { return owner_ + "::" + std::string(field); }

 private:
  [[noreturn]] void Fail(std::string_view field, double value, std::string_view rule) const;
  std::string owner_;
};

// The common rules.
inline bool InOpenUnit(double v) {
  return v > 0.0 && v < 1.0;
}

// The settings of a Newton solve with a backtracking line search, which the spring and the FEM
// equilibrium solvers share (same names, same meaning).
template <class NewtonOptions>
void CheckNewtonSettings(const OptionsCheck& check, const NewtonOptions& o) {
  // 0: converge to the round-off floor alone (the reference's polish, problem.cpp).
  check.Require(o.relative_force_tolerance >= 0.0 && o.relative_force_tolerance < 1.0,
                "relative_force_tolerance", o.relative_force_tolerance, "0 <= value < 1");
  check.Require(InOpenUnit(o.roundoff_force_tolerance), "roundoff_force_tolerance",
                o.roundoff_force_tolerance, "0 < value < 1");
  check.Require(o.max_iterations >= 1, "max_iterations", o.max_iterations, "value >= 1");
  check.Require(o.max_line_search_steps >= 1, "max_line_search_steps", o.max_line_search_steps,
                "value >= 1");
  check.Require(o.armijo > 0.0 && o.armijo < 0.5, "armijo", o.armijo, "0 < value < 0.5");
  check.Require(InOpenUnit(o.pivot_tolerance), "pivot_tolerance", o.pivot_tolerance,
                "0 < value < 1");
}

}  // namespace springfit
