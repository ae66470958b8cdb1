#include "engine/problem/small_strain.h"

#include <algorithm>
#include <vector>

#include <fmt/format.h>

#include "engine/api/problem.h"
#include "engine/api/scene.h"
#include "engine/fem/fem_model.h"

namespace springfit {

double LargestNodalDisplacement(int d, const Vector& u) {
  double largest = 0.0;
  for (Eigen::Index i = 0; i < u.size() / d; ++i)
    largest = std::max(largest, u.segment(d * i, d).norm());
  return largest;
}

double LoadsSize(int d, const std::vector<const Vector*>& responses) {
  std::vector<double> largest;
  for (const Vector* u : responses) largest.push_back(LargestNodalDisplacement(d, *u));
  if (largest.empty()) return 0.0;
  std::sort(largest.begin(), largest.end());
  return largest[largest.size() / 2];
}

double NamedLoadsSize(const Problem& problem) {
  std::vector<const Vector*> responses;
  for (const PreparedLoadCase& lc : problem.load_cases()) responses.push_back(&lc.reference);
  return LoadsSize(problem.dimension(), responses);
}

namespace {

// The strain exceeded in `fraction` of the total volume: elements by strain, largest first,
// until their volume reaches the fraction.
double StrainExceededInVolume(const std::vector<double>& strains,
                              const std::vector<double>& volumes, double fraction) {
  std::vector<std::size_t> order(strains.size());
  for (std::size_t e = 0; e < order.size(); ++e) order[e] = e;
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return strains[a] > strains[b]; });
  double total = 0.0;
  for (const double v : volumes) total += v;
  double covered = 0.0;
  for (const std::size_t e : order) {
    covered += volumes[e];
    if (covered >= fraction * total) return strains[e];
  }
  return 0.0;
}

}  // namespace

std::optional<ReferenceStrain> LinearReferenceStrain(const Problem& problem, double load_scale) {
  const Scene& scene = problem.scene();
  if (scene.reference.kind != Reference::Kind::kFem) return std::nullopt;
  for (const Material& m : scene.reference.fem.materials)
    if (m.model != MaterialModel::kLinear) return std::nullopt;
  const fem::FemModel model = fem::FemModel::Build(scene);
  const std::vector<double> volumes = model.ElementVolumes();
  ReferenceStrain judged;
  for (std::size_t k = 0; k < problem.load_cases().size(); ++k) {
    const std::vector<double> strains =
        model.ElementStrains(load_scale * problem.load_cases()[k].reference);
    const double strain = StrainExceededInVolume(strains, volumes, kStrainedVolumeFraction);
    if (!(strain > judged.strain)) continue;
    const auto largest = std::max_element(strains.begin(), strains.end());
    judged = {strain, *largest, static_cast<int>(k), static_cast<int>(largest - strains.begin())};
  }
  return judged;
}

std::optional<std::string> SmallStrainWarning(const Problem& problem, double load_size) {
  const double named = NamedLoadsSize(problem);
  const double scale = load_size > 0.0 && named > 0.0 ? load_size / named : 1.0;
  const std::optional<ReferenceStrain> s = LinearReferenceStrain(problem, scale);
  if (!s || !(s->strain > kSmallStrainLimit)) return std::nullopt;
  const std::string where = load_size > 0.0
                                ? fmt::format(
                                      "at the load range (search.load_size {:.4g}, {:.3g}x the "
                                      "named loads)",
                                      load_size, scale)
                                : std::string("under the named loads");
  return fmt::format(
      "the linear reference is loaded past small strain {}: {:.1f}% strain in {:.0f}% of the "
      "body under load_cases[{}] ('{}') (up to {:.1f}% in {}), above {:.0f}%. A linear "
      "material is the small-load limit of tissue, so the model is fitted to a response tissue "
      "does not have at this size: give the reference a nonlinear material (its \"model\": "
      "\"neo_hookean\" or \"st_venant_kirchhoff\"), or smaller loads",
      where, 100.0 * s->strain, 100.0 * kStrainedVolumeFraction, s->load_case,
      problem.scene().load_cases[static_cast<std::size_t>(s->load_case)].name, 100.0 * s->largest,
      ElementNamed(problem.scene(), static_cast<std::size_t>(s->element)),
      100.0 * kSmallStrainLimit);
}

}  // namespace springfit
