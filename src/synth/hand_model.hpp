#pragma once
/// The synthetic hand family: an anatomically proportioned adult hand, right or left, posed
/// through the project's own skeleton (posture/skeleton.hpp), as a skeleton plus a smooth
/// implicit surface around it.
///
/// Hand frame (mm): origin at the wrist joint, +X along the hand toward the middle fingertip,
/// +Z out of the back of the hand, +Y = Z × X (toward the thumb of a right hand, toward the
/// little finger of a left hand).
#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "core/dof.hpp"
#include "core/rig.hpp"

namespace handskin {

struct HandShapeOptions {
  double hand_length_mm = 185.0;   ///< wrist joint to middle fingertip (skin, flat posture); scales everything
  double finger_spread_deg = 5.0;  ///< extra angle between neighbouring fingers in the rest frame, 0..15
  double thickness_scale = 1.0;    ///< multiplies the palm's thickness, 0.7..1.4
  double width_scale = 1.0;        ///< multiplies palm and finger breadth, 0.7..1.4
  double finger_thickness_scale = 1.0;  ///< multiplies the fingers' girth (breadth and thickness), 0.7..1.4
  double finger_length_scale = 1.0;     ///< multiplies the phalanges against the palm, 0.85..1.15
  /// Index to ring finger length (phalanges), 0.85..1.05; the nominal hand's is 0.929.
  std::optional<double> index_ring_ratio;
  double thumb_abduction_deg = 40; ///< thumb metacarpal angle from the index metacarpal in the rest frame, 20..70
  /// The replica is cut this far proximal of the wrist joint (the forearm stub), 0..40 mm;
  /// unset: 12 mm × the hand's scale.
  std::optional<double> forearm_mm;
  HandSide side = HandSide::Right;
  /// Joint angles (degrees, the DOFs of formats/hand-rig.md) applied to the rest skeleton by
  /// its forward kinematics; the carpus DOFs (wrist.*) must be 0. All zero: the open, flat
  /// posture the thesis scanned.
  std::array<double, kDofCount> posture{};
  /// The thumb's sections turned about its own axis (pronation, the nail turning away from
  /// the palm), degrees 0..90. The rig cannot hold a twist, so it shapes the surface only.
  double thumb_pronation_deg = 0;
  /// False (and a message naming the option) when a value is out of range.
  bool IsValid(std::string* error) const;
};

/// A relaxed hand's posture (a plaster cast of a hand at rest): a few degrees to ~20° of
/// flexion at every finger joint, growing toward the little finger; the thumb flexed and
/// abducted out of the palm plane. `amount` scales every angle (1: the default).
std::array<double, kDofCount> relaxed_posture(double amount = 1.0);
/// The thumb pronation that goes with relaxed_posture(amount).
double relaxed_thumb_pronation(double amount = 1.0);

/// One tapered capsule with an elliptic cross-section: half-width `w` across the link,
/// half-thickness `h` along `up` (the link's dorsal direction), both linear from end a to end
/// b; centre shifted by `dz` along `up`.
struct Capsule {
  Eigen::Vector3d a, b;
  double wa, wb, ha, hb, dz;
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  double value(const Eigen::Vector3d& p) const;  ///< < 0 inside, ~ distance in mm near the surface
};

struct HandModel {
  HandShapeOptions options;
  Rig rig;                            ///< the posed joints in the hand frame, palm_normal = +Z
  Rig rest_rig;                       ///< the same hand in the flat rest posture
  /// The capsules, in the right hand's coordinates (a left hand's field mirrors them).
  std::vector<Capsule> palm;          ///< carpus, forearm stub, metacarpals, thenar, hypothenar
  std::vector<std::vector<Capsule>> fingers;  ///< per finger: phalanges and knuckle pads
  double wrist_cut_x = 0;             ///< flat wrist cut plane x = wrist_cut_x
  bool mirrored = false;              ///< a left hand: the right hand's field mirrored in y
  Eigen::Vector3d box_min, box_max;   ///< a box enclosing the surface (hand frame, the side's own)

  /// Implicit function: < 0 inside the hand, > 0 outside, smooth except at the wrist cut's rim.
  double value(const Eigen::Vector3d& p) const;
};

/// Build the skeleton and surface description. Throws InputError when the options are not
/// valid.
HandModel build_hand_model(const HandShapeOptions& options);

/// Parse a posture: "flat", "relaxed", or a joint-angle CSV (its first row; empty cells 0);
/// `sets` are "DOF=deg" overrides applied on top. Throws InputError naming the file or value.
std::array<double, kDofCount> parse_posture(const std::string& spec, const std::vector<std::string>& sets);

}  // namespace handskin
