#pragma once
/// Distance from points to a triangle mesh (CGAL AABB tree): how far a reconstruction lies
/// from the true skin, in tests and reports.
#include <Eigen/Core>
#include <memory>

#include "mesh/trimesh.hpp"

namespace handskin {

class MeshDistance {
 public:
  explicit MeshDistance(const TriMesh& mesh);
  ~MeshDistance();
  double distance(const Eigen::Vector3d& p) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace handskin
