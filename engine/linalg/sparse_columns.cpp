#include "engine/linalg/sparse_columns.h"

#include <cmath>

namespace springfit {

std::optional<UnitColumnNormal> UnitNormalOf(const SparseMatrix& a,
                                             const std::vector<bool>& usable) {
  UnitColumnNormal u;
  for (int j = 0; j < static_cast<int>(a.cols()); ++j) {
    if (usable[static_cast<std::size_t>(j)]) u.columns.push_back(j);
  }
  u.scale.resize(static_cast<Eigen::Index>(u.columns.size()));
  for (std::size_t c = 0; c < u.columns.size(); ++c) {
    const double norm = a.col(u.columns[c]).norm();
    if (!(norm > 0.0)) return std::nullopt;
    u.scale[static_cast<Eigen::Index>(c)] = 1.0 / norm;
  }
  const SparseMatrix scaled = SelectColumns(a, u.columns) * u.scale.asDiagonal();
  u.normal = SparseMatrix(scaled.transpose()) * scaled;
  return u;
}

SparseMatrix SelectColumns(const SparseMatrix& a, const std::vector<int>& columns) {
  SparseMatrix sub(a.rows(), static_cast<Eigen::Index>(columns.size()));
  // No columns: Eigen's reserve and makeCompressed on an empty matrix read past its index
  // array (AddressSanitizer, a scene without genes).
  if (columns.empty()) return sub;
  Eigen::VectorXi sizes(static_cast<Eigen::Index>(columns.size()));
  for (std::size_t c = 0; c < columns.size(); ++c) {
    sizes[static_cast<Eigen::Index>(c)] = static_cast<int>(a.col(columns[c]).nonZeros());
  }
  sub.reserve(sizes);
  for (std::size_t c = 0; c < columns.size(); ++c) {
    for (SparseMatrix::InnerIterator it(a, columns[c]); it; ++it) {
      sub.insert(it.row(), static_cast<Eigen::Index>(c)) = it.value();
    }
  }
  sub.makeCompressed();
  return sub;
}

}  // namespace springfit
