#pragma once
/// Internal to the skin library: principal axes of a point set (columns, by decreasing
/// variance) and its mean. Used by the skeleton placement (hand frame, digit axes) and by the
/// skin's fit of the line through the finger webs.
#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <vector>

namespace handskin {

template <int D>
void principal_axes(const std::vector<Eigen::Matrix<double, D, 1>>& p, Eigen::Matrix<double, D, D>* axes,
                    Eigen::Matrix<double, D, 1>* mean) {
  *mean = Eigen::Matrix<double, D, 1>::Zero();
  for (const auto& x : p) *mean += x;
  *mean /= static_cast<double>(p.size());
  Eigen::Matrix<double, D, D> C = Eigen::Matrix<double, D, D>::Zero();
  for (const auto& x : p) C += (x - *mean) * (x - *mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, D, D>> es(C);
  *axes = es.eigenvectors().rowwise().reverse();
}

}  // namespace handskin
