#include "mesh/mesh_distance.hpp"

#include <Eigen/Geometry>  // cross(): only declared by <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <vector>

#include "core/random.hpp"

#include "mesh/triangle_tree.hpp"

namespace handskin {

struct MeshDistance::Impl {
  explicit Impl(const std::vector<Eigen::Vector3d>& v, const std::vector<std::array<int, 3>>& f) : tt(v, f) {}
  cgal::TriangleTree tt;
};


MeshDistance::MeshDistance(const Mesh& mesh) : impl_(std::make_unique<Impl>(mesh.vertices, mesh.faces)) {
  impl_->tt.tree.accelerate_distance_queries();
}

MeshDistance::~MeshDistance() = default;

double MeshDistance::distance(const Eigen::Vector3d& p) const {
  return std::sqrt(impl_->tt.tree.squared_distance(cgal::point(p)));
}

std::vector<Eigen::Vector3d> sample_surface(const Mesh& mesh, double per_mm2, std::uint64_t seed) {
  const auto& V = mesh.vertices;
  const auto& F = mesh.faces;
  Rng rng(seed);
  std::vector<Eigen::Vector3d> out;
  double carry = 0;
  for (const auto& f : F) {
    const Eigen::Vector3d &a = V[f[0]], &b = V[f[1]], &c = V[f[2]];
    carry += 0.5 * (b - a).cross(c - a).norm() * per_mm2;
    for (; carry >= 1.0; carry -= 1.0) {
      double u = rng.uniform(), v = rng.uniform();
      if (u + v > 1) u = 1 - u, v = 1 - v;
      out.push_back(a + u * (b - a) + v * (c - a));
    }
  }
  return out;
}

OneWayDistance one_way_distance(const std::vector<Eigen::Vector3d>& points, const MeshDistance& to,
                                const std::vector<Eigen::Vector3d>& exclude, double exclude_radius) {
  // Every point's distance on its own (the tree's queries are const: it and its k-d tree of
  // hints were built in MeshDistance's constructor), on every thread; the kept distances are
  // then gathered in the points' order, as a sequential loop would have them.
  std::vector<double> all(points.size());
  std::vector<char> kept(points.size(), 0);
#pragma omp parallel for schedule(dynamic, 256)
  for (long k = 0; k < static_cast<long>(points.size()); ++k) {
    const Eigen::Vector3d& p = points[static_cast<size_t>(k)];
    if (std::any_of(exclude.begin(), exclude.end(), [&](const Eigen::Vector3d& e) { return (p - e).norm() < exclude_radius; }))
      continue;
    all[static_cast<size_t>(k)] = to.distance(p);
    kept[static_cast<size_t>(k)] = 1;
  }
  std::vector<double> d;
  d.reserve(all.size());
  for (size_t k = 0; k < all.size(); ++k)
    if (kept[k]) d.push_back(all[k]);
  OneWayDistance r;
  r.samples = d.size();
  if (d.empty()) return r;
  std::sort(d.begin(), d.end());
  double sum = 0;
  for (double x : d) sum += x;
  r.mean = sum / static_cast<double>(d.size());
  r.median = d[d.size() / 2];
  r.p95 = d[std::min(d.size() - 1, d.size() * 95 / 100)];
  r.max = d.back();
  r.within_1mm = static_cast<double>(std::upper_bound(d.begin(), d.end(), 1.0) - d.begin()) / static_cast<double>(d.size());
  return r;
}

}  // namespace handskin
