#pragma once
/// The hand skeleton of thesis §3.1: a tree of rigid links from the carpus (the wrist
/// joint, root) to every fingertip, a local frame at the base of each link (Y along the
/// link, X the flexion axis), 3-2-1 Euler composition and forward kinematics (eqs. 3.1–3.6).
///
/// Built from a `hand-rig/1`: link lengths and rest frames come from the joint positions, so
/// all angles zero reproduces the rig's (scan) posture exactly. Angles in degrees.
#include <Eigen/Geometry>
#include <array>
#include <vector>

#include "core/dof.hpp"
#include "core/rig.hpp"

namespace handskin {

using Angles = std::array<double, kDofCount>;  ///< one value per DOF, canonical order (degrees; wrist.t* in mm)

class Skeleton {
 public:
  /// Rest frames from a loaded rig (load_rig checks it: every joint finite, no two of one
  /// finger at the same place), which always gives them.
  explicit Skeleton(const Rig& rig);

  /// World (rig-frame) pose of every joint's local frame for the given angles.
  std::array<Eigen::Isometry3d, kJointCount> frames(const Angles& angles) const;
  /// Joint positions (rig frame, mm).
  std::array<Eigen::Vector3d, kJointCount> positions(const Angles& angles) const;

  /// Rest frame of joint j (angles all zero), rig frame.
  const Eigen::Isometry3d& rest_frame(int j) const { return rest_[j]; }
  /// Length of the link that starts at joint j (to its first child; 0 for tips).
  double link_length(int j) const { return length_[j]; }
  /// +1 or −1: the sign that makes positive abduction point away from the middle finger
  /// (a left hand's local frames are mirrored against a right hand's: its signs flip).
  static double abduction_sign(Finger f, HandSide side = HandSide::Right);
  HandSide side() const { return side_; }

  /// Local rotation of a joint from its DOF angles: Rz(abd)·Ry(0)·Rx(flex) (3-2-1 Euler,
  /// eq. 3.4 with the twist fixed at zero); the wrist: Rz(rz)·Ry(ry)·Rx(rx).
  static Eigen::Matrix3d euler321(double z_deg, double y_deg, double x_deg);

 private:
  std::array<Eigen::Isometry3d, kJointCount> rest_;      ///< rest frame, rig frame
  std::array<Eigen::Isometry3d, kJointCount> local_;     ///< rest frame relative to the parent's rest frame
  std::array<double, kJointCount> length_{};
  std::array<int, kJointCount> flex_{}, abd_{};          ///< DOF index per joint, -1 if none
  HandSide side_ = HandSide::Right;
};

}  // namespace handskin
