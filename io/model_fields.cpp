#include "io/model_fields.h"

#include <cctype>
#include <set>

namespace springfit::io {

std::string FieldName(std::string_view text) {
  std::string name(text);
  for (char& c : name) {
    const bool keep =
        std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.';
    if (!keep) c = '_';
  }
  return name.empty() ? "_" : name;
}

std::vector<PointField> PointFieldsOf(const SpringModel& model) {
  const int n = model.node_count();
  const int d = model.dimension;
  std::vector<PointField> fields;
  std::set<std::string> used;
  const auto unique = [&](std::string name) {
    std::string candidate = name;
    for (int k = 2; !used.insert(candidate).second; ++k) candidate = name + "_" + std::to_string(k);
    return candidate;
  };
  if (!model.node_tags.empty()) {
    fields.push_back({unique("node_tag"), 1, true,
                      std::vector<double>(model.node_tags.begin(), model.node_tags.end())});
  }
  if (!model.mass.empty()) fields.push_back({unique("mass"), 1, false, model.mass});
  for (const auto& [name, nodes] : model.node_sets) {
    PointField f{unique("set_" + FieldName(name)), 1, true,
                 std::vector<double>(static_cast<std::size_t>(n), 0.0)};
    for (int p : nodes) f.values[static_cast<std::size_t>(p)] = 1.0;
    fields.push_back(std::move(f));
  }
  // A displacement in 3D (z = 0 in 2D), node-major.
  const auto vector3 = [&](const std::vector<double>& flat) {
    std::vector<double> v(3 * static_cast<std::size_t>(n), 0.0);
    for (int p = 0; p < n; ++p)
      for (int c = 0; c < d; ++c)
        v[static_cast<std::size_t>(3 * p + c)] = flat[static_cast<std::size_t>(d * p + c)];
    return v;
  };
  for (const auto& lc : model.load_cases) {
    const std::string name = FieldName(lc.name);
    const std::vector<double> reference = vector3(lc.reference_displacement);
    fields.push_back({unique("u_reference_" + name), 3, false, reference});
    if (lc.model_displacement.empty()) continue;
    std::vector<double> own = vector3(lc.model_displacement);
    std::vector<double> error = own;
    for (std::size_t i = 0; i < error.size(); ++i) error[i] -= reference[i];
    fields.push_back({unique("u_model_" + name), 3, false, std::move(own)});
    fields.push_back({unique("u_error_" + name), 3, false, std::move(error)});
  }
  return fields;
}

}  // namespace springfit::io
