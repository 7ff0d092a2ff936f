#pragma once
/// Automatic skeleton placement (issue 5, step 1): the thesis placed the joints in the merged
/// cloud by hand. Here the hand's frame, the five digits and their axes are found in the
/// cloud, and the joints are put along the measured axes with anatomical proportions
/// (core/hand_proportions.hpp) scaled to the measured hand.
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "core/rig.hpp"

namespace handskin {

/// A digit's bones lie this far (nominal mm) dorsal of the middle of its cross-sections (the
/// palmar pad is the thicker side): where the placement puts them, and centre_digit_links.
constexpr double kDigitBoneDorsalMm = 1.0;

struct AutoRig {
  Rig rig;                  ///< palm frame (the cloud's), palm_normal set
  double scale = 1;         ///< measured hand / nominal proportions
  double palm_radius_mm = 0; ///< largest circle inscribed in the palm's silhouette
  HandSide side = HandSide::Right;
  std::vector<std::string> notes;
  /// The same skeleton with the thumb's base (CMC) on the thumb's own centre line, the
  /// metacarpal's length (chord) back from its MCP, instead of where the proportions put it
  /// in the palm's frame. The skin stage builds on it when it refuses `rig` (a thumb raised
  /// and turned out of the palm plane, whose links then cross the thenar off its sections).
  Rig thumb_base_on_line;
};

/// How the five digits are told apart.
enum class DigitParting {
  Silhouette,  ///< the silhouette (closed, then unclosed); the sheets when it gives fewer than five
  Sheets,      ///< the sheets only: each digit's points from the back's and the palm's sheets
};

/// How a finger's centre line is found (auto_rig_axes.cpp).
enum class CentreLines {
  Quadratic,  ///< sections at fixed distances along the hand: a lateral line, a quadratic height
  Traced,     ///< each finger's line traced in its flexion plane, slab by slab (follows a finger
              ///< curled past what a quadratic does; no better on straight ones: a fallback)
};

/// Place the 25 joints in a merged cloud (palm frame, mm) of an open hand, right or left,
/// its digits straight or curled. `sides` labels each point 0 (palm scan) or 1 (back scan),
/// which orients the back normal and gives the sheets; 2 marks a point of neither sheet (a
/// cloud seen from around: its flanks, which neither a back nor a palm scan sees). Throws
/// InputError when five digits and a wrist cannot be told apart (e.g. a digit missing).
AutoRig place_skeleton(const std::vector<Eigen::Vector3d>& points, const std::vector<std::uint32_t>& sides,
                       DigitParting parting = DigitParting::Silhouette,
                       CentreLines lines = CentreLines::Quadratic);

struct JointError {
  double mean_mm = 0, max_mm = 0;
  std::string worst_joint;
};
/// Distances between the same joints of two rigs (same frame).
JointError joint_error(const Rig& estimate, const Rig& reference);

}  // namespace handskin
