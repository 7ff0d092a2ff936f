#pragma once
/// Distance from points to a triangle mesh (CGAL AABB tree): how far a reconstruction lies
/// from the true skin, in tests and reports.
#include <Eigen/Core>
#include <memory>
#include <vector>

#include "mesh/mesh.hpp"

namespace handskin {

class MeshDistance {
 public:
  explicit MeshDistance(const Mesh& mesh);
  ~MeshDistance();
  double distance(const Eigen::Vector3d& p) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Points spread over a mesh's surface, uniformly by area (`per_mm2` per mm², at least one per
/// triangle's share), from a fixed seed.
std::vector<Eigen::Vector3d> sample_surface(const Mesh& mesh, double per_mm2, std::uint64_t seed = 1);

/// One-way distance figures from samples of surface A to surface B (mm).
struct OneWayDistance {
  double mean = 0, median = 0, p95 = 0, max = 0;
  double within_1mm = 0;  ///< fraction of the samples within 1 mm
  size_t samples = 0;
};
/// Distances from `points` to `to`, skipping points within `exclude_radius` of any of
/// `exclude` (e.g. the markers, whose skin no scan measured).
OneWayDistance one_way_distance(const std::vector<Eigen::Vector3d>& points, const MeshDistance& to,
                                const std::vector<Eigen::Vector3d>& exclude = {}, double exclude_radius = 0);

}  // namespace handskin
