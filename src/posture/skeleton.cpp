#include "posture/skeleton.hpp"

#include <cmath>

#include "core/errors.hpp"

namespace handskin {

namespace {
constexpr double kRad = M_PI / 180.0;
}

double Skeleton::abduction_sign(Finger f, HandSide side) {
  // A positive rotation about the local Z (= X × Y) swings the link toward −X, the little-
  // finger side (X, the flexion axis, points toward the thumb). Away from the middle finger
  // is toward the thumb for thumb and index (and, by convention, the middle finger itself).
  // A left hand's flexion axes (back × link) point toward its little finger: mirrored.
  const double s = (f == Finger::Ring || f == Finger::Little) ? 1.0 : -1.0;
  return side == HandSide::Left ? -s : s;
}

Eigen::Matrix3d Skeleton::euler321(double z_deg, double y_deg, double x_deg) {
  return (Eigen::AngleAxisd(z_deg * kRad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(y_deg * kRad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(x_deg * kRad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Skeleton::Skeleton(const Rig& rig) {
  const auto& J = joints();
  // The back-of-hand normal and the hand's axes from the rig (palm_normal when given).
  const Eigen::Isometry3d T_hand_rig = hand_frame_from_rig(rig);
  const Eigen::Matrix3d hand_axes = T_hand_rig.linear().transpose();  // columns: hand X, Y, Z in rig frame
  const Eigen::Vector3d back = hand_axes.col(2);
  side_ = rig_side(rig);

  std::array<int, kJointCount> first_child;
  first_child.fill(-1);
  for (int j = kJointCount - 1; j > 0; --j) first_child[J[j].parent] = j;  // lowest index child wins
  for (int j = 0; j < kJointCount; ++j) {
    Eigen::Isometry3d F = Eigen::Isometry3d::Identity();
    F.translation() = rig.joints[j];
    if (j == 0) {
      // Carpus: the hand frame, but with Y along the hand (toward the middle MCP) and X the
      // flexion axis (toward the thumb), like every other link.
      F.linear().col(0) = hand_axes.col(1);
      F.linear().col(1) = hand_axes.col(0);
      F.linear().col(2) = -hand_axes.col(2);
      length_[j] = (rig.joints[joint_index("middle-finger-metacarpal").value()] - rig.joints[0]).norm();
    } else if (first_child[j] >= 0) {
      const Eigen::Vector3d d = rig.joints[first_child[j]] - rig.joints[j];
      length_[j] = d.norm();
      const Eigen::Vector3d y = d / length_[j];
      Eigen::Vector3d x = back.cross(y);  // flexion axis: +flexion swings the link toward the palm
      if (x.norm() < 0.1) {
        // A link within ~6 deg of the back-of-hand normal (a finger curled into a fist: its
        // distal phalanx points at the palm) has no flexion axis of its own there: it takes
        // its parent's, square to the link. A finger flexes about parallel axes, and the two
        // agree wherever both are defined (no abduction between them).
        // (The parent's X is square to the back-of-hand normal, so to this link too.)
        x = rest_[J[j].parent].linear().col(0);
        x -= x.dot(y) * y;
      }
      x.normalize();
      F.linear().col(0) = x;
      F.linear().col(1) = y;
      F.linear().col(2) = x.cross(y);
    } else {
      F.linear() = rest_[J[j].parent].linear();  // a tip: its parent's orientation
    }
    rest_[j] = F;
    local_[j] = j == 0 ? F : Eigen::Isometry3d(rest_[J[j].parent].inverse() * F);
  }
  flex_.fill(-1);
  abd_.fill(-1);
  for (int d = 0; d < kDofCount; ++d) {
    const DofInfo& info = dofs()[d];
    if (info.kind == DofKind::Flexion) flex_[info.joint] = d;
    if (info.kind == DofKind::Abduction) abd_[info.joint] = d;
  }
}

std::array<Eigen::Isometry3d, kJointCount> Skeleton::frames(const Angles& a) const {
  const auto& J = joints();
  std::array<Eigen::Isometry3d, kJointCount> W;
  // Carpus: translate (model frame), then rotate about its own rest axes (3-2-1).
  Eigen::Isometry3d root = local_[0];
  root.linear() = rest_[0].linear() * euler321(a[5], a[4], a[3]);
  root.pretranslate(Eigen::Vector3d(a[0], a[1], a[2]));
  W[0] = root;
  for (int j = 1; j < kJointCount; ++j) {
    Eigen::Isometry3d L = local_[j];
    if (flex_[j] >= 0) {
      const double abd = abd_[j] >= 0 ? abduction_sign(*J[j].finger, side_) * a[abd_[j]] : 0.0;
      L.linear() = L.linear() * euler321(abd, 0.0, a[flex_[j]]);
    }
    W[j] = W[J[j].parent] * L;
  }
  return W;
}

std::array<Eigen::Vector3d, kJointCount> Skeleton::positions(const Angles& a) const {
  const auto W = frames(a);
  std::array<Eigen::Vector3d, kJointCount> p;
  for (int j = 0; j < kJointCount; ++j) p[j] = W[j].translation();
  return p;
}

}  // namespace handskin
