#include "engine/probe_fit/mode_cuts.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "engine/runtime/options_check.h"

namespace springfit::response {

void ModeHoldOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  check.Require(weight >= 0.0 && std::isfinite(weight), "weight", weight, "value >= 0");
  check.Require(target > 0.0 && std::isfinite(target), "target", target, "value > 0");
  check.Require(modes_per_support >= 1, "modes_per_support", modes_per_support, "value >= 1");
  check.Require(max_cuts >= 1, "max_cuts", max_cuts, "value >= 1");
}

Vector ModeSlope(const GeneSprings& springs, const SoftMode& mode, const SupportSystem& reference) {
  const Vector v = reference.Gather(mode.shape);
  const double energy = v.dot(reference.Multiply(v));  // v^T K_ref v
  return Elongations(springs, mode.shape).cwiseAbs2() / energy;
}

ModeCuts::ModeCuts(const ModeHoldOptions& options, Vector scale)
    : options_(options), scale_(std::move(scale)) {
  options_.Validate();
}

void ModeCuts::Add(const GeneSprings& springs, const SoftMode& mode,
                   const SupportSystem& reference) {
  if (static_cast<int>(cuts_.size()) >= options_.max_cuts) cuts_.erase(cuts_.begin());
  cuts_.push_back(ModeSlope(springs, mode, reference).cwiseProduct(scale_));
}

double ModeCuts::Shortfall(std::size_t j, const Vector& x) const {
  return std::max(0.0, options_.target - cuts_[j].dot(x));
}

double ModeCuts::Penalty(const Vector& x) const {
  double sum = 0.0;
  for (std::size_t j = 0; j < cuts_.size(); ++j) sum += std::pow(Shortfall(j, x), 2);
  return options_.weight * sum;
}

Vector ModeCuts::HalfGradient(const Vector& x) const {
  Vector g = Vector::Zero(x.size());
  for (std::size_t j = 0; j < cuts_.size(); ++j) g -= options_.weight * Shortfall(j, x) * cuts_[j];
  return g;
}

Vector ModeCuts::HalfHessianProduct(const Vector& x, const Vector& v) const {
  Vector y = Vector::Zero(x.size());
  for (std::size_t j = 0; j < cuts_.size(); ++j)
    if (Shortfall(j, x) > 0.0) y += options_.weight * cuts_[j].dot(v) * cuts_[j];
  return y;
}

Vector ModeCuts::HalfHessianDiagonal(const Vector& x) const {
  Vector y = Vector::Zero(x.size());
  for (std::size_t j = 0; j < cuts_.size(); ++j)
    if (Shortfall(j, x) > 0.0) y += options_.weight * cuts_[j].cwiseAbs2();
  return y;
}

}  // namespace springfit::response
