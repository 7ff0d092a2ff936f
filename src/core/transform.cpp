#include "core/transform.hpp"

#include <cmath>

#include "core/errors.hpp"

namespace handskin {

Json isometry_to_json(const Eigen::Isometry3d& T) {
  Json rows = Json::array();
  const Eigen::Matrix4d M = T.matrix();
  for (int r = 0; r < 4; ++r) rows.push_back(Json::array({M(r, 0), M(r, 1), M(r, 2), M(r, 3)}));
  return rows;
}

Eigen::Isometry3d isometry_from_json(const Json& j, const std::string& what, const std::string& file) {
  if (!j.is_array() || j.size() != 4) throw InputError(file, what + " must be 4 rows of 4 numbers");
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r) {
    if (!j[r].is_array() || j[r].size() != 4) throw InputError(file, what + " must be 4 rows of 4 numbers");
    for (int c = 0; c < 4; ++c) {
      if (!j[r][c].is_number() || !std::isfinite(j[r][c].get<double>()))
        throw InputError(file, what + " must hold finite numbers");
      M(r, c) = j[r][c].get<double>();
    }
  }
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-6 || R.determinant() < 0 ||
      (M.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9)
    throw InputError(file, what + " is not a proper rigid transform");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = M.topRightCorner<3, 1>();
  return T;
}

double rotation_difference_deg(const Eigen::Isometry3d& A, const Eigen::Isometry3d& B) {
  const Eigen::AngleAxisd aa(A.linear().transpose() * B.linear());
  return aa.angle() * 180.0 / M_PI;
}

}  // namespace handskin
