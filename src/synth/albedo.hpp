#pragma once
/// The synthetic hand's skin colour (albedo), for the scanner's photos: what a colour camera
/// beside the range finder would see of the plaster replica if it had been painted like the
/// hand it was cast from. Procedural and deterministic, placed by the hand's own skeleton so
/// that it follows any posture and proportion of the family:
/// - skin tone, darker and warmer on the back than on the palm, with a faint mottle;
/// - the palm's three flexion creases (distal and proximal transverse, thenar), the fingers'
///   palmar creases at their base, PIP and DIP, and faint wrinkles over the dorsal PIPs;
/// - nails on the dorsal side of every distal phalanx, with a lighter free edge.
#include <Eigen/Core>
#include <vector>

#include "core/rig.hpp"

namespace handskin {

class SkinAlbedo {
 public:
  /// `rig_hand`: the joints in the hand frame of `hand_frame_from_rig` (X toward the middle
  /// MCP, Z out of the back).
  explicit SkinAlbedo(const Rig& rig_hand);
  /// Colour (0..1 RGB) at a surface point with its outward unit normal, hand frame.
  Eigen::Vector3f colour(const Eigen::Vector3d& p, const Eigen::Vector3d& n) const;

 private:
  struct Crease {
    std::vector<Eigen::Vector2d> line;  ///< polyline in the hand frame's X–Y plane
    double width, depth;
  };
  Rig rig_;
  std::vector<Bone> bones_;
  std::vector<Crease> palm_creases_;
};

}  // namespace handskin
