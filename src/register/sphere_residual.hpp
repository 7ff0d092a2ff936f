#pragma once
/// The residual shared by every sphere fit in registration: a sample's distance to a
/// sphere of known radius about a centre (the parameter block), times its depth weight.
#include <ceres/ceres.h>

#include <Eigen/Core>

namespace handskin {

struct SphereResidual {
  SphereResidual(const Eigen::Vector3d& p, double radius, double weight) : p_(p), r_(radius), w_(weight) {}
  template <typename T>
  bool operator()(const T* c, T* res) const {
    const T dx = T(p_.x()) - c[0], dy = T(p_.y()) - c[1], dz = T(p_.z()) - c[2];
    res[0] = T(w_) * (ceres::sqrt(dx * dx + dy * dy + dz * dz) - T(r_));
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector3d& p, double radius, double weight) {
    return new ceres::AutoDiffCostFunction<SphereResidual, 1, 3>(new SphereResidual(p, radius, weight));
  }

 private:
  Eigen::Vector3d p_;
  double r_, w_;
};

}  // namespace handskin
