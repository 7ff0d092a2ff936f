#pragma once
/// A cloud from any scanner, made ready for the skin (issue 37): the counterpart of
/// prepare_scan for unorganized points, which have no range grid, no table and no markers.
/// prepare_cloud runs these steps in order (cloud_prep.cpp):
///   1. check_scale          the cloud's extent at the given units: a hand, or an error that
///                           names the extent and the units that would make it one
///   2. downsample           a voxel grid (PCL VoxelGrid): each voxel's points averaged, which
///                           evens out the views' overlaps and averages the noise
///   3. drop_outliers        isolated points (PCL RadiusOutlierRemoval's rule)
///   4. drop_support         the stand or turntable: a RANSAC plane (PCL sample_consensus, register/sac.hpp)
///                           that holds a share of the points most of which lie away from
///                           everything else
///   5. keep_largest_part    the hand as the largest connected part (Euclidean clusters)
///   6. check_hand           enough points left, and a hand's size
///   7. estimate_normals     normals from the neighbours' spread, unless the file had them;
///                           each point moved onto its neighbours' plane (the noise averaged)
/// Sides (palm / back labels, which the skin's steps and figures use as a scan pair's) are
/// given afterwards by label_sides, once the back's direction is known.
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace handskin {

struct CloudPrepOptions {
  double voxel_mm = 0.7;              ///< downsampling voxel (0: none)
  int outlier_neighbours = 4;         ///< outliers: fewer other points than this …
  double outlier_radius_mm = 2.0;     ///< … within this distance
  bool remove_support = true;
  double support_inlier_mm = 1.0;     ///< RANSAC plane inlier distance
  double support_min_share = 0.02;    ///< a support plane holds at least this share of the points
  double support_clear_mm = 5.0;      ///< … and most of them are this far from any point off it
  double part_gap_mm = 0;             ///< connected parts: points nearer than this; 0 = 4 × spacing, ≥ 1.5 mm
  double min_hand_mm = 80, max_hand_mm = 450;  ///< the hand's largest extent
  long min_points = 2000;             ///< fewer left: not enough of a hand
  double normal_radius_mm = 1.2;      ///< normals (and smoothing) from the points within this distance
  bool smooth = true;                 ///< each point onto its neighbours' plane (averages the noise)
  bool IsValid(std::string* error) const;
};

/// The hand's points and what each step took away.
struct PreparedCloud {
  std::vector<Eigen::Vector3d> points, normals;  ///< mm, the cloud's frame; normals unit, unoriented
  bool normals_from_file = false;
  double voxel_mm = 0;       ///< the voxel used
  size_t read = 0, downsampled = 0, outliers = 0, support = 0, other_parts = 0, parts = 0;
  bool support_found = false;
  Eigen::Vector4d support_plane = Eigen::Vector4d::Zero();  ///< n·p + d = 0 (when found)
  double spacing_mm = 0;     ///< the points' spacing: the voxel after a voxel grid, else the median nearest-neighbour distance
  double part_gap_mm = 0;    ///< the gap used for connected parts
  double noise_mm = 0;       ///< the points' noise after the voxel grid (a local plane's spread, median; 0 when not measured)
  double support_band_mm = 0;  ///< the support plane's inlier band (each side) used
  Eigen::Vector3d extent_mm = Eigen::Vector3d::Zero();  ///< the hand's extents along its principal axes, largest first
  std::vector<std::pair<std::string, double>> timings_ms;  ///< per step, in order
};

/// Prepare a cloud read from `file` (named in errors) at `units` (named in the scale check's
/// message). `normals`: the file's, or empty. Throws InputError naming the file: a cloud too
/// small or large for a hand at these units, a plane only, too few points left.
PreparedCloud prepare_cloud(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& normals,
                            const std::string& file, const std::string& units, const CloudPrepOptions& options);

/// Palm (0) and back (1) labels for a hand's points, the back toward `back`: a point above
/// the hand's mid-surface along `back` (halfway between the highest and lowest point of its
/// 2 mm column, and its neighbours') is on the back. Normals are turned to agree.
std::vector<std::uint32_t> label_sides(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& back,
                                       std::vector<Eigen::Vector3d>* normals);

/// How much of the hand the cloud holds from both sides: of the 2 mm columns along `back` that
/// hold points, the share whose points span more than 4 mm along it (a back and a palm surface,
/// or a steep flank). A hand seen all round: 0.92-0.98 (synth cloud of the fixture and the
/// family, 3 views or more; the WebXR fixed hand 0.98); seen from one side only: under 0.1.
double two_sided_share(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& back);

/// Unoriented normals: the least-spread axis of the points within `radius` of each (zero
/// where fewer than 6 lie there).
std::vector<Eigen::Vector3d> neighbour_normals(const std::vector<Eigen::Vector3d>& points, double radius);

/// The thickness axis of a hand's points (the principal axis of least spread), unit.
Eigen::Vector3d thickness_axis(const std::vector<Eigen::Vector3d>& points);

}  // namespace handskin
