// A k-d tree over a fixed set of points in 2D or 3D (nanoflann), for the neighbour queries
// that would otherwise compare every pair: coincident nodes in validation, k-nearest and
// radius candidates, the memetic search's swap partners. Building costs O(n log n), a query
// O(log n + answers), so a scene of n nodes is prepared in O(n log n) whatever its layout.
//
// Answers are exact and deterministic: the tree only proposes points, and every distance that
// decides is recomputed here in one way (Eigen's norm of the difference), so a result does not
// depend on the tree's own round-off or on the order in which it visits points. Ties are
// broken by the lower index, as a sort of (distance, index) pairs would.
#pragma once

#include <memory>
#include <vector>

#include "engine/linalg/linalg.h"

namespace springfit {

class PointIndex {
 public:
  // `points` holds n points of `dimension` (2 or 3) coordinates each, node-major (point i at
  // [d*i, d*i + d)), finite. The index keeps its own copy.
  PointIndex(const Vector& points, int dimension);
  ~PointIndex();
  PointIndex(const PointIndex&) = delete;
  PointIndex& operator=(const PointIndex&) = delete;

  int size() const { return static_cast<int>(points_.size() / dimension_); }

  // The distance between points i and j (the one every query decides by).
  double Distance(int i, int j) const;
  double DistanceTo(const Vector& query, int j) const;

  // Every point j with DistanceTo(query, j) <= radius, in increasing index order.
  std::vector<int> WithinRadius(const Vector& query, double radius) const;

  // The k points nearest to point i, excluding i itself, ordered by (distance, index): the
  // first k of all other points sorted that way. k is clipped to size() - 1.
  std::vector<int> Nearest(int i, int k) const;

  Vector Point(int i) const { return points_.segment(dimension_ * i, dimension_); }

 private:
  struct Tree;
  Vector points_;
  int dimension_;
  std::unique_ptr<Tree> tree_;
};

}  // namespace springfit
