#include "engine/model/point_index.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <nanoflann.hpp>

namespace springfit {
namespace {

// The tree proposes every point within the asked distance times (1 + kSlack); the exact test
// is then made here. The two ways of computing a distance differ by a few ulps, far below this.
constexpr double kSlack = 1e-9;

}  // namespace

// Named, not anonymous: PointIndex::Tree, declared in the header, holds these (GCC warns of a
// member whose type has internal linkage once this file is not its translation unit's main
// file, as in a unity build).
namespace point_index_detail {

// nanoflann's view of the flat coordinate vector.
struct Cloud {
  const Vector* points;
  int dimension;
  std::size_t kdtree_get_point_count() const {
    return static_cast<std::size_t>(points->size() / dimension);
  }
  double kdtree_get_pt(std::size_t i, std::size_t a) const {
    return (*points)[static_cast<Eigen::Index>(dimension * i + a)];
  }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;  // let the tree compute it
  }
};

using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Cloud>,
                                                   Cloud, -1, std::size_t>;

}  // namespace point_index_detail

struct PointIndex::Tree {
  point_index_detail::Cloud cloud;
  point_index_detail::KdTree tree;
  Tree(const Vector* points, int dimension)
      : cloud{points, dimension},
        tree(dimension, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16)) {}
};

PointIndex::PointIndex(const Vector& points, int dimension)
    : points_(points), dimension_(dimension) {
  tree_ = std::make_unique<Tree>(&points_, dimension_);
}

PointIndex::~PointIndex() = default;

double PointIndex::Distance(int i, int j) const {
  const int d = dimension_;
  return (points_.segment(d * i, d) - points_.segment(d * j, d)).norm();
}

double PointIndex::DistanceTo(const Vector& query, int j) const {
  return (query - points_.segment(dimension_ * j, dimension_)).norm();
}

std::vector<int> PointIndex::WithinRadius(const Vector& query, double radius) const {
  std::vector<std::pair<std::size_t, double>> found;
  // nanoflann keeps distances strictly below its radius: one ulp more keeps those on it (and a
  // radius of 0 finds the points at the query).
  const double r = radius * (1.0 + kSlack);
  const double r2 = std::nextafter(r * r, std::numeric_limits<double>::infinity());
  tree_->tree.radiusSearch(query.data(), r2, found, nanoflann::SearchParams(32, 0, false));
  std::vector<int> out;
  out.reserve(found.size());
  for (const auto& [j, d2] : found) {
    if (DistanceTo(query, static_cast<int>(j)) <= radius) out.push_back(static_cast<int>(j));
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<int> PointIndex::Nearest(int i, int k) const {
  k = std::min(k, size() - 1);
  if (k <= 0) return {};
  const Vector query = Point(i);
  // The k-th nearest other point's distance (the tree may order ties either way; its k + 1
  // nearest include i itself at distance 0) ...
  std::vector<std::size_t> index(static_cast<std::size_t>(k) + 1);
  std::vector<double> distance2(static_cast<std::size_t>(k) + 1);
  const std::size_t got =
      tree_->tree.knnSearch(query.data(), index.size(), index.data(), distance2.data());
  double kth = 0.0;
  for (std::size_t m = 0; m < got; ++m) {
    if (static_cast<int>(index[m]) != i)
      kth = std::max(kth, DistanceTo(query, static_cast<int>(index[m])));
  }
  // ... then every point within it, ordered by (distance, index) and cut at k, so that ties at
  // the k-th distance go to the lower index whatever the tree's order.
  std::vector<std::pair<double, int>> by_distance;
  for (const int j : WithinRadius(query, kth * (1.0 + kSlack))) {
    if (j != i) by_distance.emplace_back(DistanceTo(query, j), j);
  }
  std::sort(by_distance.begin(), by_distance.end());
  std::vector<int> out;
  for (int r = 0; r < k && r < static_cast<int>(by_distance.size()); ++r)
    out.push_back(by_distance[r].second);
  return out;
}

}  // namespace springfit
