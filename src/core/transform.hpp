#pragma once
/// Rigid transforms in files: 4 x 4, row-major, `p_to = T * p_from` (formats/cubist-range.md).
#include <Eigen/Geometry>

#include "core/json_util.hpp"

namespace handskin {

Json isometry_to_json(const Eigen::Isometry3d& T);
/// Parse a 4 x 4 row-major matrix; it must be a proper rigid transform (det +1, orthonormal).
Eigen::Isometry3d isometry_from_json(const Json& j, const std::string& what, const std::string& file);
/// Rotation angle (degrees) of A⁻¹B.
double rotation_difference_deg(const Eigen::Isometry3d& A, const Eigen::Isometry3d& B);

}  // namespace handskin
