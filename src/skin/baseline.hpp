#pragma once
/// What a user would otherwise do with the merged cloud: Poisson surface reconstruction
/// (Kazhdan's, as PCL ships it; issue 5's baseline), to compare the strip skin against in
/// accuracy, triangle count and time. Opt-in (`--baseline`): it takes seconds.
#include <Eigen/Core>
#include <vector>

#include "mesh/mesh.hpp"

namespace handskin {

struct BaselineResult {
  Mesh mesh;
  double seconds = 0;
  size_t points_used = 0;
  size_t faces_dropped = 0;  ///< faces the mesh could not take (they would make an edge non-manifold)
  double average_spacing_mm = 0;
};

/// Every how many points to take so that at most `max_points` of `n` are used (≥ 1).
size_t thinning_step(size_t n, size_t max_points);
/// At most `max_points` of `points`, every thinning_step-th.
std::vector<Eigen::Vector3d> thinned_points(const std::vector<Eigen::Vector3d>& points, size_t max_points);

/// Poisson reconstruction (CGAL, Delaunay refinement meshing of the implicit function) of
/// oriented points; every k-th point is used so that at most `max_points` go in.
BaselineResult poisson_baseline(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& normals,
                                size_t max_points = 40000);

}  // namespace handskin
