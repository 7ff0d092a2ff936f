#include "synth/mesh_distance.hpp"

#include <cmath>
#include <vector>

#include "synth/triangle_tree.hpp"

namespace handskin {

struct MeshDistance::Impl {
  explicit Impl(const std::vector<Eigen::Vector3d>& v, const std::vector<std::array<int, 3>>& f) : tt(v, f) {}
  cgal::TriangleTree tt;
};

namespace {
std::vector<Eigen::Vector3d> vertices_of(const TriMesh& mesh) {
  std::vector<Eigen::Vector3d> v;
  for (auto vh : mesh.vertices()) v.emplace_back(mesh.point(vh)[0], mesh.point(vh)[1], mesh.point(vh)[2]);
  return v;
}
std::vector<std::array<int, 3>> faces_of(const TriMesh& mesh) {
  std::vector<std::array<int, 3>> f;
  for (auto fh : mesh.faces()) {
    std::array<int, 3> t{};
    int k = 0;
    for (auto vh : mesh.fv_range(fh)) t[k++] = vh.idx();
    f.push_back(t);
  }
  return f;
}
}  // namespace

MeshDistance::MeshDistance(const TriMesh& mesh) : impl_(std::make_unique<Impl>(vertices_of(mesh), faces_of(mesh))) {
  impl_->tt.tree.accelerate_distance_queries();
}

MeshDistance::~MeshDistance() = default;

double MeshDistance::distance(const Eigen::Vector3d& p) const {
  return std::sqrt(impl_->tt.tree.squared_distance(cgal::point(p)));
}

}  // namespace handskin
