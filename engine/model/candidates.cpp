#include "engine/model/candidates.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <unordered_map>

#include "engine/model/point_index.h"
#include "engine/runtime/input_error.h"

namespace springfit {
namespace {

// Nodes within this fraction of a lattice step of their lattice point count as on it.
constexpr double kLatticeTolerance = 1e-6;
// A rest distance within this relative difference of the radius counts as on it, so that
// round-off in generated coordinates does not decide.
constexpr double kDistanceTolerance = 1e-9;

NodePair Ordered(int a, int b) {
  return a < b ? NodePair{a, b} : NodePair{b, a};
}

void SortUnique(std::vector<NodePair>& pairs) {
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
}

std::vector<NodePair> GridCandidates(const Scene& scene) {
  const int d = scene.dimension;
  const int n = scene.node_count();
  std::vector<double> spacing = scene.candidates.spacing;
  if (spacing.empty()) spacing = InferLatticeSpacing(scene);
  const Vector lo = scene.Bounds().lo;

  // Integer lattice coordinates, packed into one key (21 bits per axis is plenty).
  std::vector<std::array<long, 3>> cell(n, {0, 0, 0});
  std::unordered_map<long long, int> at;
  at.reserve(n * 2);
  auto key = [](const std::array<long, 3>& c) {
    return (static_cast<long long>(c[0]) << 42) ^ (static_cast<long long>(c[1]) << 21) ^
           static_cast<long long>(c[2]);
  };
  for (int i = 0; i < n; ++i) {
    for (int a = 0; a < d; ++a) {
      const double offset = scene.rest[d * i + a] - lo[a];
      if (spacing[a] == 0.0) continue;  // all nodes share this coordinate
      const double steps = offset / spacing[a];
      cell[i][a] = std::lround(steps);
      if (std::abs(steps - static_cast<double>(cell[i][a])) > kLatticeTolerance) {
        throw InputError("candidates", "grid candidates need every node on a lattice of step " +
                                           std::to_string(spacing[a]) + " along axis " +
                                           std::to_string(a) + "; nodes[" + std::to_string(i) +
                                           "] is off it");
      }
      if (cell[i][a] >= (1L << 20)) {
        throw InputError("candidates", "grid has more than 2^20 steps along an axis");
      }
    }
    const auto [it, inserted] = at.emplace(key(cell[i]), i);
    if (!inserted) {
      throw InputError("candidates", "nodes[" + std::to_string(it->second) + "] and nodes[" +
                                         std::to_string(i) + "] fall on the same lattice point");
    }
  }
  std::vector<NodePair> pairs;
  for (int i = 0; i < n; ++i) {
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = (d == 3 ? -1 : 0); dz <= (d == 3 ? 1 : 0); ++dz) {
          if (dx == 0 && dy == 0 && dz == 0) continue;
          std::array<long, 3> c = cell[i];
          c[0] += dx;
          c[1] += dy;
          c[2] += dz;
          if (c[0] < 0 || c[1] < 0 || c[2] < 0) continue;
          const auto it = at.find(key(c));
          if (it != at.end() && it->second > i) pairs.push_back({i, it->second});
        }
      }
    }
  }
  return pairs;
}

std::vector<NodePair> NearestCandidates(const Scene& scene, const PointIndex& index) {
  const int n = scene.node_count();
  std::vector<NodePair> pairs;
  pairs.reserve(static_cast<std::size_t>(n) * std::min(scene.candidates.k, n - 1));
  for (int i = 0; i < n; ++i) {
    // Exact ties go to the lower index (PointIndex::Nearest orders by distance, then index).
    for (const int j : index.Nearest(i, scene.candidates.k)) pairs.push_back(Ordered(i, j));
  }
  return pairs;
}

std::vector<NodePair> RadiusCandidates(const Scene& scene, const PointIndex& index) {
  const int n = scene.node_count();
  const double r = scene.candidates.radius * (1.0 + kDistanceTolerance);
  std::vector<NodePair> pairs;
  for (int i = 0; i < n; ++i) {
    for (const int j : index.WithinRadius(index.Point(i), r)) {
      if (j > i) pairs.push_back({i, j});
    }
  }
  return pairs;
}

}  // namespace

std::vector<double> InferLatticeSpacing(const Scene& scene) {
  const int d = scene.dimension;
  const int n = scene.node_count();
  std::vector<double> spacing(d, 0.0);
  std::vector<double> coords(n);
  for (int a = 0; a < d; ++a) {
    for (int i = 0; i < n; ++i) coords[i] = scene.rest[d * i + a];
    std::sort(coords.begin(), coords.end());
    const double extent = coords.back() - coords.front();
    double step = 0.0;
    for (int i = 1; i < n; ++i) {
      const double gap = coords[i] - coords[i - 1];
      // Gaps within round-off of the extent are the same coordinate.
      if (gap > kLatticeTolerance * extent && (step == 0.0 || gap < step)) step = gap;
    }
    spacing[a] = step;
  }
  return spacing;
}

std::int64_t EstimateCandidateCount(const Scene& scene, std::int64_t stop_above) {
  const std::int64_t n = scene.node_count();
  const std::int64_t k =
      std::min<std::int64_t>(scene.candidates.k, std::max<std::int64_t>(n - 1, 0));
  switch (scene.candidates.kind) {
    case CandidateSpec::Kind::kGrid:
      return n * (scene.dimension == 3 ? 13 : 4);  // half of the 26 or 8 neighbours
    case CandidateSpec::Kind::kNearest:
      return n * k;
    case CandidateSpec::Kind::kPairs:
      return static_cast<std::int64_t>(scene.candidates.pairs.size());
    case CandidateSpec::Kind::kMesh: {
      std::int64_t edges = 0;
      for (const std::vector<int>& element : scene.reference.fem.elements) {
        const auto m = static_cast<std::int64_t>(element.size());
        edges += m * (m - 1) / 2;
      }
      return edges + n * k;
    }
    case CandidateSpec::Kind::kRadius: {
      if (!scene.rest.allFinite() || n < 2) return 0;
      const PointIndex index(scene.rest, scene.dimension);
      const double r = scene.candidates.radius * (1.0 + kDistanceTolerance);
      std::int64_t count = 0;
      for (int i = 0; i < n && count <= stop_above; ++i) {
        for (const int j : index.WithinRadius(index.Point(i), r)) count += j > i ? 1 : 0;
      }
      return count;
    }
  }
  return 0;
}

std::vector<NodePair> GenerateCandidates(const Scene& scene) {
  std::vector<NodePair> pairs;
  switch (scene.candidates.kind) {
    case CandidateSpec::Kind::kGrid:
      pairs = GridCandidates(scene);
      break;
    case CandidateSpec::Kind::kNearest:
      pairs = NearestCandidates(scene, PointIndex(scene.rest, scene.dimension));
      break;
    case CandidateSpec::Kind::kRadius:
      pairs = RadiusCandidates(scene, PointIndex(scene.rest, scene.dimension));
      break;
    case CandidateSpec::Kind::kPairs:
      for (const NodePair& p : scene.candidates.pairs) pairs.push_back(Ordered(p.first, p.second));
      break;
    case CandidateSpec::Kind::kMesh:
      for (const std::vector<int>& element : scene.reference.fem.elements) {
        for (std::size_t a = 0; a < element.size(); ++a) {
          for (std::size_t b = a + 1; b < element.size(); ++b)
            pairs.push_back(Ordered(element[a], element[b]));
        }
      }
      if (scene.candidates.k > 0) {
        const std::vector<NodePair> near =
            NearestCandidates(scene, PointIndex(scene.rest, scene.dimension));
        pairs.insert(pairs.end(), near.begin(), near.end());
      }
      break;
  }
  SortUnique(pairs);
  return pairs;
}

}  // namespace springfit
