#pragma once
/// The default hand: an anatomically proportioned adult right hand in the open, flat posture
/// the thesis scanned, as a skeleton plus a smooth implicit surface around it.
///
/// Hand frame (mm): origin at the wrist joint, +X along the hand toward the middle
/// fingertip, +Y toward the thumb (radial side), +Z out of the back of the hand.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/rig.hpp"

namespace handskin {

struct HandShapeOptions {
  double hand_length_mm = 185.0;   ///< wrist joint to middle fingertip (skin); scales everything
  double finger_spread_deg = 5.0;  ///< extra angle between neighbouring fingers, 0..15
  double thickness_scale = 1.0;    ///< multiplies palm and finger thickness, 0.7..1.4
  double width_scale = 1.0;        ///< multiplies palm and finger breadth, 0.7..1.4
  double thumb_abduction_deg = 40; ///< thumb metacarpal angle from the index metacarpal, 20..70
  /// False (and a message naming the option) when a value is out of range.
  bool IsValid(std::string* error) const;
};

/// One tapered capsule with an elliptic cross-section: half-width `w` across the hand,
/// half-thickness `h` along +Z, both linear from end a to end b; centre shifted by `dz` in Z.
struct Capsule {
  Eigen::Vector3d a, b;
  double wa, wb, ha, hb, dz;
  double value(const Eigen::Vector3d& p) const;  ///< < 0 inside, ~ distance in mm near the surface
};

struct HandModel {
  HandShapeOptions options;
  Rig rig;                            ///< joints in the hand frame, palm_normal = +Z
  std::vector<Capsule> palm;          ///< carpus, forearm stub, metacarpals, thenar, hypothenar
  std::vector<std::vector<Capsule>> fingers;  ///< per finger: phalanges and knuckle pads
  double wrist_cut_x = 0;             ///< flat wrist cut plane x = wrist_cut_x
  Eigen::Vector3d box_min, box_max;   ///< a box enclosing the surface

  /// Implicit function: < 0 inside the hand, > 0 outside, smooth except at the wrist cut's rim.
  double value(const Eigen::Vector3d& p) const;
};

/// Build the skeleton and surface description. Options must be valid.
HandModel build_hand_model(const HandShapeOptions& options);

}  // namespace handskin
