#pragma once
/// The residual shared by every sphere fit in registration: a sample's depth error against
/// a sphere, in the sample's own scanner frame.
///
/// A range scan measures depth along Z; X and Y are the exact grid position. So the error of
/// a sample is z − (c_z + √(r² − ρ²)), ρ its distance from the centre across Z: the
/// scanner's own error model. The geometric distance |p − c| − r, even divided by |n_z| to
/// put it in depth units (as these fits did before), is that error only to first order: its
/// second-order terms make a free-radius fit of a marker cap 0.005–0.04 mm small (simulated
/// caps of 2.5–4 mm, σ 0.05–0.1 mm, step 0.2 mm), where the depth error is unbiased
/// (docs/registration.md).
#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

namespace handskin {

/// z − (c_z + √(r² − ρ²)). Near the sphere's outline, where a depth error stands for a
/// sideways one of any size, the sphere's height is held at ≥ `floor` × r (the steepest
/// surface a scanner returns: n_z ≥ floor) and continued as a straight line in r² − ρ²
/// below it, so a sample just outside the outline (noise, a centre still moving) has a
/// large but finite residual with a continuous derivative.
template <typename T>
T sphere_depth_error(const T* p, const T* c, const T& r, double floor) {
  const T dx = p[0] - c[0], dy = p[1] - c[1];
  const T h2 = r * r - dx * dx - dy * dy;
  const T h2_min = T(floor * floor) * r * r;
  const T h = h2 > h2_min ? ceres::sqrt(h2) : ceres::sqrt(h2_min) + (h2 - h2_min) / (T(2.0) * ceres::sqrt(h2_min));
  return p[2] - c[2] - h;
}

/// A sample on a sphere of known radius about a centre (the parameter block).
struct SphereResidual {
  SphereResidual(const Eigen::Vector3d& p, double radius, double floor) : p_(p), r_(radius), floor_(floor) {}
  template <typename T>
  bool operator()(const T* c, T* res) const {
    const T p[3] = {T(p_.x()), T(p_.y()), T(p_.z())};
    res[0] = sphere_depth_error(p, c, T(r_), floor_);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector3d& p, double radius, double floor) {
    return new ceres::AutoDiffCostFunction<SphereResidual, 1, 3>(new SphereResidual(p, radius, floor));
  }

 private:
  Eigen::Vector3d p_;
  double r_, floor_;
};

/// A sample's geometric distance to a sphere of known radius, |p − c| − r, divided by the
/// sphere's slope max(floor, |n_z|) at the sample seen from `start` (so, in depth units, to
/// first order): the coarse rounds that find a cap from a start millimetres off use it, where
/// the depth error, steep near an outline that is still in the wrong place, has no wide basin.
struct SphereDistanceResidual {
  SphereDistanceResidual(const Eigen::Vector3d& p, double radius, double weight) : p_(p), r_(radius), w_(weight) {}
  template <typename T>
  bool operator()(const T* c, T* res) const {
    const T dx = T(p_.x()) - c[0], dy = T(p_.y()) - c[1], dz = T(p_.z()) - c[2];
    res[0] = T(w_) * (ceres::sqrt(dx * dx + dy * dy + dz * dz) - T(r_));
    return true;
  }
  /// The sample's weight: 1 / its sphere's slope seen from `start`.
  static double weight(const Eigen::Vector3d& p, const Eigen::Vector3d& start, double radius, double floor) {
    return 1.0 / std::max(floor, std::abs(p.z() - start.z()) / radius);
  }
  static ceres::CostFunction* Create(const Eigen::Vector3d& p, const Eigen::Vector3d& start, double radius, double floor) {
    return new ceres::AutoDiffCostFunction<SphereDistanceResidual, 1, 3>(
        new SphereDistanceResidual(p, radius, weight(p, start, radius, floor)));
  }

 private:
  Eigen::Vector3d p_;
  double r_, w_;
};

/// A sample on a sphere whose centre and radius are both parameter blocks.
struct FreeRadiusResidual {
  FreeRadiusResidual(const Eigen::Vector3d& p, double floor) : p_(p), floor_(floor) {}
  template <typename T>
  bool operator()(const T* c, const T* r, T* res) const {
    const T p[3] = {T(p_.x()), T(p_.y()), T(p_.z())};
    res[0] = sphere_depth_error(p, c, r[0], floor_);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector3d& p, double floor) {
    return new ceres::AutoDiffCostFunction<FreeRadiusResidual, 1, 3, 1>(new FreeRadiusResidual(p, floor));
  }

 private:
  Eigen::Vector3d p_;
  double floor_;
};

/// pose = (angle-axis, translation): q = R p + t, back frame → palm frame. A back sample's
/// depth error is measured in the back scanner's frame, against the centre carried there:
/// c_back = Rᵀ (c − t).
struct BackOnSphere {
  BackOnSphere(const Eigen::Vector3d& p, double r, double floor) : p_(p), r_(r), floor_(floor) {}
  template <typename T>
  bool operator()(const T* pose, const T* c, T* res) const {
    const T inverse[3] = {-pose[0], -pose[1], -pose[2]};
    const T shifted[3] = {c[0] - pose[3], c[1] - pose[4], c[2] - pose[5]};
    T cb[3];
    ceres::AngleAxisRotatePoint(inverse, shifted, cb);
    const T p[3] = {T(p_.x()), T(p_.y()), T(p_.z())};
    res[0] = sphere_depth_error(p, cb, T(r_), floor_);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector3d& p, double r, double floor) {
    return new ceres::AutoDiffCostFunction<BackOnSphere, 1, 6, 3>(new BackOnSphere(p, r, floor));
  }
  Eigen::Vector3d p_;
  double r_, floor_;
};

/// The covariance of one parameter block (`size` values) of a solved problem, (JᵀJ)⁻¹ scaled
/// by the residuals' own variance (their sum of squares over residuals − parameters), into
/// `covariance` (row-major) and that standard deviation into `sigma`: the fit's error when
/// its residuals are the noise. Dense SVD: these problems have tens of parameters, and it says
/// when rank is lost. False when it cannot be formed.
inline bool residual_scaled_covariance(ceres::Problem* problem, const double* block, int size, double* covariance,
                                       double* sigma) {
  const int n = problem->NumResiduals(), params = problem->NumParameters();
  if (n <= params) return false;
  double cost = 0;
  if (!problem->Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, nullptr)) return false;
  const double var = 2.0 * cost / static_cast<double>(n - params);
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  co.null_space_rank = -1;
  ceres::Covariance cov(co);
  const std::vector<std::pair<const double*, const double*>> blocks = {{block, block}};
  if (!cov.Compute(blocks, problem) || !cov.GetCovarianceBlock(block, block, covariance)) return false;
  for (int k = 0; k < size * size; ++k) covariance[k] *= var;
  *sigma = std::sqrt(var);
  return true;
}

}  // namespace handskin
