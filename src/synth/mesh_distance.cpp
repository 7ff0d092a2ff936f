#include "synth/mesh_distance.hpp"

#include <cmath>
#include <vector>

#include "synth/triangle_tree.hpp"

namespace handskin {

struct MeshDistance::Impl {
  explicit Impl(const std::vector<Eigen::Vector3d>& v, const std::vector<std::array<int, 3>>& f) : tt(v, f) {}
  cgal::TriangleTree tt;
};


MeshDistance::MeshDistance(const TriMesh& mesh) : impl_(std::make_unique<Impl>(mesh_vertices(mesh), mesh_faces(mesh))) {
  impl_->tt.tree.accelerate_distance_queries();
}

MeshDistance::~MeshDistance() = default;

double MeshDistance::distance(const Eigen::Vector3d& p) const {
  return std::sqrt(impl_->tt.tree.squared_distance(cgal::point(p)));
}

}  // namespace handskin
