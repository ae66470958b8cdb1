#include "engine/api/scene.h"

#include <cmath>
#include <utility>
#include <vector>

#include "engine/runtime/input_error.h"

namespace springfit {
namespace {

using Table = std::vector<std::pair<const char*, double>>;  // name, in SI units

const Table kLengths = {{"m", 1.0}, {"cm", 1e-2}, {"mm", 1e-3}, {"um", 1e-6}};
const Table kForces = {{"kN", 1e3}, {"N", 1.0}, {"mN", 1e-3}, {"uN", 1e-6}};
const Table kModuli = {{"GPa", 1e9}, {"MPa", 1e6}, {"kPa", 1e3}, {"Pa", 1.0}};
const Table kMasses = {{"t", 1e3}, {"kg", 1.0}, {"g", 1e-3}, {"mg", 1e-6}};

std::string Names(const Table& table) {
  std::string text;
  for (const auto& [name, factor] : table) text += (text.empty() ? "" : ", ") + std::string(name);
  return text;
}

double FactorOf(const Table& table, const std::string& name, const std::string& path) {
  for (const auto& [n, factor] : table)
    if (name == n) return factor;
  throw InputError(path, "unknown unit '" + name + "' (expected " + Names(table) + ")");
}

// The table's name for `factor`, or empty.
std::string NameOf(const Table& table, double factor) {
  for (const auto& [name, f] : table)
    if (std::abs(f - factor) <= 1e-9 * f) return name;
  return "";
}

}  // namespace

DerivedUnits DeriveUnits(const Scene::Units& units) {
  DerivedUnits d;
  d.length = units.length;
  d.force = units.force;
  const double length = FactorOf(kLengths, units.length, "units.length");
  const double force = FactorOf(kForces, units.force, "units.force");
  d.stiffness = units.force + "/" + units.length;
  const double modulus = force / (length * length);
  const std::string derived = NameOf(kModuli, modulus);
  d.modulus = derived.empty() ? units.force + "/" + units.length + "^2" : derived;
  const std::string mass = NameOf(kMasses, force / length);  // (force x s^2 / length, in kg)
  d.mass = mass.empty() ? units.force + " s^2/" + units.length : mass;
  if (!units.modulus.empty()) {
    const double given = FactorOf(kModuli, units.modulus, "units.modulus");
    if (std::abs(given - modulus) > 1e-9 * given) {
      // What would make it consistent: the modulus the others imply, or the force unit.
      const std::string force_fix = NameOf(kForces, given * length * length);
      throw InputError("units.modulus",
                       "'" + units.modulus + "' is not force / length^2: " + units.force + "/" +
                           units.length + "^2 is " + d.modulus +
                           ", so moduli and forces would be read " +
                           std::to_string(static_cast<long long>(
                               std::llround(given > modulus ? given / modulus : modulus / given))) +
                           " times apart; write modulus '" + d.modulus + "'" +
                           (force_fix.empty() ? std::string() : " or force '" + force_fix + "'"));
    }
  }
  return d;
}

}  // namespace springfit
