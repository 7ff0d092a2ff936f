#include "synth/mesh_distance.hpp"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <cmath>
#include <vector>

namespace handskin {

namespace {
using K = CGAL::Simple_cartesian<double>;
using Triangle = K::Triangle_3;
using TriIter = std::vector<Triangle>::const_iterator;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, CGAL::AABB_triangle_primitive<K, TriIter>>>;
}  // namespace

struct MeshDistance::Impl {
  std::vector<Triangle> tris;
  Tree tree;
};

MeshDistance::MeshDistance(const TriMesh& mesh) : impl_(std::make_unique<Impl>()) {
  for (auto fh : mesh.faces()) {
    K::Point_3 p[3];
    int k = 0;
    for (auto vh : mesh.fv_range(fh)) {
      const auto& q = mesh.point(vh);
      p[k++] = K::Point_3(q[0], q[1], q[2]);
    }
    impl_->tris.emplace_back(p[0], p[1], p[2]);
  }
  impl_->tree.insert(impl_->tris.begin(), impl_->tris.end());
  impl_->tree.build();
  impl_->tree.accelerate_distance_queries();
}

MeshDistance::~MeshDistance() = default;

double MeshDistance::distance(const Eigen::Vector3d& p) const {
  return std::sqrt(impl_->tree.squared_distance(K::Point_3(p.x(), p.y(), p.z())));
}

}  // namespace handskin
