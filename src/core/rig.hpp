#pragma once
/// The `hand-rig/1` file: the 25 joint positions of the skeleton inside the scan, in the
/// model (palm-scan) frame, millimetres (formats/hand-rig.md).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "core/dof.hpp"

namespace handskin {

struct Rig {
  std::string frame = "palm";                       ///< frame the joints are expressed in
  std::array<Eigen::Vector3d, kJointCount> joints;  ///< indexed as handskin::joints(), mm
  std::optional<Eigen::Vector3d> palm_normal;       ///< unit, out of the back of the hand
};

/// Parse and validate rig JSON text (`file` names it in errors). Every joint required,
/// unknown or duplicated names, non-finite values and coincident joints of one finger are
/// errors naming the joint.
Rig parse_rig(const std::string& text, const std::string& file);
Rig load_rig(const std::string& file);
std::string rig_to_json_text(const Rig& rig);
void save_rig(const std::string& file, const Rig& rig);

enum class HandSide { Right, Left };
const char* hand_side_name(HandSide s);

/// Which hand a rig is: in its hand frame (below) a right hand's thumb lies on +Y, a left
/// hand's on −Y. Needs palm_normal to tell a left hand from a right hand seen from its palm
/// (without it the frame's Z is taken toward the back of a right hand).
HandSide rig_side(const Rig& rig);

/// Hand frame from a rig: origin at the wrist, X toward the middle MCP, Z out of the back
/// (palm_normal when given), Y = Z × X (toward the thumb of a right hand, the little finger of a left one). Returns T_hand_rig.
Eigen::Isometry3d hand_frame_from_rig(const Rig& rig);

/// A bone link: the segment from joint `joint` to joint `child` (rig frame). Links from the
/// wrist to each metacarpal base are the carpus.
struct Bone {
  int joint = -1, child = -1;
  Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();
  std::string name() const;
};
/// The 24 links of a rig: wrist → each metacarpal base, and every joint → its child.
std::vector<Bone> bones_from_rig(const Rig& rig);
/// Distance from p to the link's segment a–b (mm).
double distance_to_bone(const Eigen::Vector3d& p, const Bone& bone);

}  // namespace handskin
