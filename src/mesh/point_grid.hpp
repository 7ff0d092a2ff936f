#pragma once
/// Points in a uniform hash grid of `cell` mm: the nearest point within a radius (exact) and
/// every point within a radius. Faster here than a k-d tree: the queries land within a cell or
/// two of their answers. Header-only; the grid keeps its own copy of the points' positions.
///
/// Layout: every cell's points are one run of `index_` (ascending indices, as the points were
/// given) and of `sorted_` (their positions, copied so that a cell's are read side by side),
/// found through an open-addressing table from the cell's packed coordinates to its run. Until
/// 2026-12-02 it was an `std::unordered_map` of one `std::vector` of indices per cell: one heap
/// block per cell, a bucket's node chased on each lookup, the points read from wherever they
/// lay (built over a merged cloud of ~180 000 points at 1 mm: 12 → 7 ms; a nearest-point query
/// 1.5–2 times faster). The answers, and the order `within` reports points in, are the same:
/// cells visited in the same order, each cell's points in ascending index (test
/// `PointGrid.AnswersAsABruteForceSearch`).
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace handskin {

class PointGrid {
 public:
  PointGrid(const std::vector<Eigen::Vector3d>& pts, double cell) : cell_(cell) {
    const size_t n = pts.size();
    // The table starts at a quarter of the points' count (a cell holds a few points in this
    // project's uses) and doubles whenever it is half full.
    size_t slots = 16;
    bits_ = 4;
    while (slots < n / 4) slots *= 2, ++bits_;
    keys_.assign(slots, kEmpty);
    cell_of_slot_.assign(slots, 0);
    std::vector<std::uint32_t> cell_of_point(n);
    std::vector<std::uint32_t> count;
    for (size_t k = 0; k < n; ++k) {
      const std::int64_t key = pack(coords(pts[k]));
      size_t s = find(key);
      if (keys_[s] == kEmpty) {
        if (2 * (count.size() + 1) > keys_.size()) {
          grow();
          s = find(key);
        }
        keys_[s] = key;
        cell_of_slot_[s] = static_cast<std::uint32_t>(count.size());
        count.push_back(0);
      }
      cell_of_point[k] = cell_of_slot_[s];
      ++count[cell_of_slot_[s]];
    }
    // Each cell's run: the counts' prefix sums, then the points in ascending index.
    start_.assign(count.size() + 1, 0);
    for (size_t c = 0; c < count.size(); ++c) start_[c + 1] = start_[c] + count[c];
    index_.resize(n);
    sorted_.resize(n);
    std::vector<std::uint32_t> next(start_.begin(), start_.end() - 1);
    for (size_t k = 0; k < n; ++k) {
      const std::uint32_t i = next[cell_of_point[k]]++;
      index_[i] = static_cast<int>(k), sorted_[i] = pts[k];
    }
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
      visit_ring(c, ring, [&](int k, const Eigen::Vector3d& p) {
        const double d2 = (p - q).squaredNorm();
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
      visit_ring(c, ring, [&](int, const Eigen::Vector3d& p) { found = found || (p - q).squaredNorm() < radius * radius; });
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
      visit_ring(c, ring, [&](int k, const Eigen::Vector3d& p) {
        if ((p - q).squaredNorm() <= radius * radius) f(k);
      });
  }

 private:
  static constexpr std::int64_t kEmpty = -1;  // packed coordinates are 63 bits: never negative

  template <class F>
  void visit_ring(const Eigen::Vector3i& c, int ring, F&& f) const {
    for (int dx = -ring; dx <= ring; ++dx)
      for (int dy = -ring; dy <= ring; ++dy) {
        // On the ring's shell: every z when x or y is on it, else only its two ends.
        const bool shell = std::abs(dx) == ring || std::abs(dy) == ring;
        for (int dz = -ring; dz <= ring; dz += shell ? 1 : 2 * ring) {
          const size_t s = find(pack(c + Eigen::Vector3i(dx, dy, dz)));
          if (keys_[s] == kEmpty) continue;
          const std::uint32_t cell = cell_of_slot_[s];
          for (std::uint32_t i = start_[cell]; i < start_[cell + 1]; ++i) f(index_[i], sorted_[i]);
        }
      }
  }
  /// The key's slot, or the empty slot where it would go (linear probing).
  size_t find(std::int64_t key) const {
    size_t s = slot_of(key);
    while (keys_[s] != kEmpty && keys_[s] != key) s = (s + 1) & (keys_.size() - 1);
    return s;
  }
  size_t slot_of(std::int64_t key) const {
    // Fibonacci hashing: the product's high bits, as many as the table's size has.
    const std::uint64_t h = static_cast<std::uint64_t>(key) * 0x9E3779B97F4A7C15ull;
    return static_cast<size_t>(h >> (64 - bits_)) & (keys_.size() - 1);
  }
  void grow() {
    std::vector<std::int64_t> keys = std::move(keys_);
    std::vector<std::uint32_t> cells = std::move(cell_of_slot_);
    keys_.assign(2 * keys.size(), kEmpty);
    cell_of_slot_.assign(keys_.size(), 0);
    ++bits_;
    for (size_t s = 0; s < keys.size(); ++s)
      if (keys[s] != kEmpty) {
        const size_t t = find(keys[s]);  // keys are distinct: the empty slot it goes to
        keys_[t] = keys[s], cell_of_slot_[t] = cells[s];
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
  double cell_;
  std::vector<std::int64_t> keys_;           ///< the table: a cell's packed coordinates, or kEmpty
  std::vector<std::uint32_t> cell_of_slot_;  ///< the table: the cell's number (its run's place in start_)
  std::vector<std::uint32_t> start_;         ///< cell c's points are index_[start_[c], start_[c + 1])
  std::vector<int> index_;
  std::vector<Eigen::Vector3d> sorted_;      ///< the position of point index_[i]: a cell's points side by side in memory
  int bits_ = 0;
};

}  // namespace handskin
