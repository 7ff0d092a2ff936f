#pragma once
/// Registration of the back scan into the palm scan's frame (thesis §4.1.1), automatic:
///   prepare (table and speckle removed, normals) → marker spheres in each scan →
///   matching by distance pattern → rigid fit of the centres → guarded refinement →
///   checks against the marker radius and the scanner's resolution → merged cloud.
/// Stages live in prepare/spheres/match/refine; this file runs them and reports.
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Geometry>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/json_util.hpp"
#include "register/match.hpp"
#include "register/prepare.hpp"
#include "register/refine.hpp"
#include "register/spheres.hpp"
#include "scan/cubist_io.hpp"

namespace handskin {

struct RegistrationOptions {
  PrepareOptions prepare;
  SphereOptions spheres;
  RefineOptions refine;
  long expected_markers = 9;       ///< a different count found is a warning, not an error
  double match_tolerance_mm = 0.5; ///< marker distances must agree this well between the scans
  /// A matched marker whose centres disagree by more than this after the fit stops the
  /// registration; 0 = automatic: max(2 × the depth step, 10 % of the marker radius).
  double accept_residual_mm = 0;
  double marker_clearance_mm = 0.5;  ///< samples within radius + this of a marker are not skin
  bool refine_enabled = true;
  /// A warning when the fit's own error estimate (1σ, `uncertainty` in registration.json)
  /// exceeds these: the scans do not hold the transform that well (docs/registration.md).
  double warn_rotation_sigma_deg = 0.02;
  double warn_displacement_sigma_mm = 0.05;
  /// The markers' radius is not known: estimate it from the scans (spheres.radius_mm is
  /// then ignored). Each candidate radius is tried in both scans and its bumps matched
  /// between them; the one that matches the most markers wins, and one radius fitted to those
  /// caps is re-detected at itself until it settles (docs/registration.md).
  bool estimate_radius = false;
  std::vector<double> radius_candidates_mm = {2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 6.0, 7.0, 8.0};
  bool IsValid(std::string* error) const;
};

/// The markers' radius as found in the scans.
struct RadiusEstimate {
  double radius_mm = 0;      ///< trimmed median free-radius fit over the best candidate's matched caps
  double spread_mm = 0;      ///< median absolute deviation of those fits
  double candidate_mm = 0;   ///< the candidate radius that found them
  int caps = 0;              ///< caps (both scans) the estimate rests on
  Json tried = Json::array();  ///< per candidate: bumps found in each scan, and matched
};

/// Approximate marker centres per scan for a replica whose bumps the detector misses
/// (`handskin-markers/1`). A side given replaces detection on that side.
struct MarkerHints {
  std::string file;
  std::optional<std::vector<Eigen::Vector3d>> back, palm;
};
MarkerHints load_marker_hints(const std::string& file);

/// Merged cloud point: x y z, normal, label = side (0 palm, 1 back); palm frame.
using MergedCloud = pcl::PointCloud<pcl::PointXYZLNormal>;
constexpr std::uint32_t kSidePalm = 0, kSideBack = 1;

/// The merged cloud as plain arrays (double precision), for the stages that follow.
struct MergedArrays {
  std::vector<Eigen::Vector3d> points, normals;
  std::vector<std::uint32_t> sides;
};
MergedArrays merged_arrays(const MergedCloud& cloud);

/// The registration's quality figures, typed (the run report's "registration" stage).
struct RegistrationFigures {
  bool radius_estimated = false;          ///< the markers' radius was estimated (else given)
  size_t markers_back = 0, markers_palm = 0, markers_matched = 0;
  double marker_only_rms_mm = 0, refined_rms_mm = 0;        ///< matched centres' residuals
  double sphere_rms_marker_only_mm = 0, sphere_rms_refined_mm = 0;
  double icp_overlap_fraction = 0;
  /// The fit's own error estimate (1σ; 0 when it could not be made): rotation angle, and
  /// RMS displacement of the back scan's skin (with the radius estimate's share when estimated).
  double rotation_sigma_deg = 0, displacement_sigma_mm = 0;
  size_t merged_points = 0;
  std::vector<std::pair<std::string, double>> timings_ms;  ///< per step, in order
};

struct Registration {
  Eigen::Isometry3d back_to_palm = Eigen::Isometry3d::Identity();  ///< p_palm = T · p_back
  Eigen::Isometry3d marker_only = Eigen::Isometry3d::Identity();   ///< the rigid fit of the centres
  bool refined = false;                                             ///< the refinement was kept
  double marker_radius_mm = 0;                ///< used: given, or estimated from the scans
  std::vector<Eigen::Vector3d> markers_palm;  ///< matched marker centres, palm frame
  std::vector<std::string> warnings;
  MergedCloud::Ptr merged;
  RegistrationFigures figures;
  Json report;                                ///< registration.json: every detail (docs/formats.md)
};

using RegisterProgress = std::function<void(const std::string&)>;

/// Register `back` into `palm`'s frame. `back_file` / `palm_file` name the scans in errors.
/// Throws InputError when the result cannot be trusted (too few or unmatched markers, an
/// ambiguous pattern, residuals beyond the marker radius and scanner resolution).
Registration register_scans(const RangeScan& back, const RangeScan& palm, const std::string& back_file,
                            const std::string& palm_file, const RegistrationOptions& options,
                            const MarkerHints* hints, const RegisterProgress& progress);

/// How far an estimated back_to_palm is from the true one, over points of the true skin
/// (palm frame): rotation angle, and mean / max displacement of the points.
struct RegistrationError {
  double rotation_deg = 0, mean_mm = 0, max_mm = 0;
};
RegistrationError registration_error(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& truth,
                                     const std::vector<Eigen::Vector3d>& skin_palm);

/// Binary PLY, atomically (x y z nx ny nz label curvature; label 0 = palm, 1 = back).
void save_merged(const std::string& path, const MergedCloud& cloud);
/// Read a merged cloud written by save_merged. Throws InputError naming the file when it
/// cannot be read, is empty, or holds non-finite points or normals.
MergedCloud::Ptr load_merged(const std::string& path);

}  // namespace handskin
