#pragma once
/// Points in a uniform hash grid of `cell` mm: the nearest point within a radius (exact) and
/// every point within a radius. Faster here than a k-d tree: the queries land within a cell or
/// two of their answers. Header-only; the grid keeps a reference to the points.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace handskin {

class PointGrid {
 public:
  PointGrid(const std::vector<Eigen::Vector3d>& pts, double cell) : pts_(pts), cell_(cell) {
    for (size_t k = 0; k < pts.size(); ++k) cells_[pack(coords(pts[k]))].push_back(static_cast<int>(k));
  }

  /// The nearest point within `radius` (ties: the lower index), or -1. Rings of cells are
  /// searched outward until no nearer point can lie beyond them.
  int nearest(const Eigen::Vector3d& q, double radius) const {
    const Eigen::Vector3i c = coords(q);
    int best = -1;
    double bd2 = radius * radius;
    const int max_ring = static_cast<int>(std::ceil(radius / cell_)) + 1;
    for (int ring = 0; ring <= max_ring; ++ring) {
      // Points in this ring's cells are at least (ring - 1) cells away.
      if (best >= 0 && (ring - 1) * cell_ > std::sqrt(bd2)) break;
      visit_ring(c, ring, [&](int k) {
        const double d2 = (pts_[k] - q).squaredNorm();
        if (d2 < bd2 || (d2 == bd2 && best >= 0 && k < best)) bd2 = d2, best = k;
      });
    }
    return best;
  }

  /// Whether any point lies within `radius` of `q`: the nearest cells first, the first point
  /// found ends the search (what `nearest(q, radius) >= 0` says, without finding the nearest).
  bool any_within(const Eigen::Vector3d& q, double radius) const {
    const Eigen::Vector3i c = coords(q);
    const int rings = static_cast<int>(std::ceil(radius / cell_));
    for (int ring = 0; ring <= rings; ++ring) {
      bool found = false;
      visit_ring(c, ring, [&](int k) { found = found || (pts_[k] - q).squaredNorm() < radius * radius; });
      if (found) return true;
    }
    return false;
  }

  /// `f(index)` for every point within `radius` of `q`.
  template <class F>
  void within(const Eigen::Vector3d& q, double radius, F&& f) const {
    const Eigen::Vector3i c = coords(q);
    const int rings = static_cast<int>(std::ceil(radius / cell_));
    for (int ring = 0; ring <= rings; ++ring)
      visit_ring(c, ring, [&](int k) {
        if ((pts_[k] - q).squaredNorm() <= radius * radius) f(k);
      });
  }

 private:
  template <class F>
  void visit_ring(const Eigen::Vector3i& c, int ring, F&& f) const {
    for (int dx = -ring; dx <= ring; ++dx)
      for (int dy = -ring; dy <= ring; ++dy)
        for (int dz = -ring; dz <= ring; ++dz) {
          if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != ring) continue;
          const auto it = cells_.find(pack(c + Eigen::Vector3i(dx, dy, dz)));
          if (it != cells_.end())
            for (const int k : it->second) f(k);
        }
  }
  Eigen::Vector3i coords(const Eigen::Vector3d& p) const {
    return Eigen::Vector3i(static_cast<int>(std::floor(p.x() / cell_)), static_cast<int>(std::floor(p.y() / cell_)),
                           static_cast<int>(std::floor(p.z() / cell_)));
  }
  static std::int64_t pack(const Eigen::Vector3i& c) {
    return (static_cast<std::int64_t>(c.x() & 0x1FFFFF) << 42) | (static_cast<std::int64_t>(c.y() & 0x1FFFFF) << 21) |
           static_cast<std::int64_t>(c.z() & 0x1FFFFF);
  }
  const std::vector<Eigen::Vector3d>& pts_;
  double cell_;
  std::unordered_map<std::int64_t, std::vector<int>> cells_;
};

}  // namespace handskin
