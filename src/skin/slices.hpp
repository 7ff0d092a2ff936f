#pragma once
/// Skin, steps 2–4 (thesis §4.1.2–4.1.3, Figs. 4.4–4.5): cross-section planes across the
/// hand's long axis, each measured point given to its nearest bone link, and per plane and
/// link a polar resampling about the link (eqs. 4.1–4.2). Better than the thesis: radii are
/// smoothed across neighbouring planes (no wrinkle noise) and a closed section's angular
/// gaps — the flanks neither scan saw — are bridged by interpolation around the section.
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "core/rig.hpp"

namespace handskin {

struct SliceOptions {
  int planes = 50;               ///< cross-section planes from the wrist cut to the fingertips
  int points_per_segment = 10;   ///< resampled points per plane and link (eq. 4.1)
  int smoothing = 1;             ///< radii averaged over ± this many neighbouring planes (1-2-1 weights)
  /// Angular gaps at least this wide split a link's profile into arcs (each resampled with
  /// points_per_segment points); a profile without one is closed and wraps around.
  double closed_gap_deg = 60;
  long min_points = 4;           ///< fewer points of a link in a plane: no section there
  bool IsValid(std::string* error) const;
};

/// One plane's resampled section of one link.
struct Section {
  int plane = -1, bone = -1;
  bool closed = false;             ///< the samples go all the way round
  int arcs = 0;                    ///< open: how many separate arcs the samples cover
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< where the link meets the plane (rig frame)
  std::vector<double> phi;         ///< sample angles (rad) about the centre, in the plane
  std::vector<double> rho;         ///< sample radii (mm), after smoothing across planes
  std::vector<double> rho_raw;     ///< the same from this plane's points alone
  std::vector<Eigen::Vector3d> points;  ///< samples, rig frame
  size_t measured = 0;             ///< measured points of this link in the plane's slab
  double largest_gap_deg = 0;      ///< widest angular stretch without a measured point
};

struct Slicing {
  Eigen::Isometry3d T_hand_rig = Eigen::Isometry3d::Identity();  ///< slicing frame: X along the hand
  std::vector<double> plane_x;     ///< plane positions along the hand frame's X (mm)
  double spacing = 0;              ///< between planes; each plane takes the points within ±spacing/2
  std::vector<Bone> bones;
  std::vector<Section> sections;
  size_t points = 0;
};

/// Slice `points` (rig frame, mm) with the hand frame of `rig`. Throws InputError when the
/// points do not span the rig (e.g. a rig from another scan) or too few remain.
Slicing slice_cloud(const std::vector<Eigen::Vector3d>& points, const Rig& rig, const SliceOptions& options);
/// The same with explicit bones and slicing frame (for tests and other skeletons).
Slicing slice_cloud(const std::vector<Eigen::Vector3d>& points, const std::vector<Bone>& bones,
                    const Eigen::Isometry3d& T_hand_rig, const SliceOptions& options);

}  // namespace handskin
