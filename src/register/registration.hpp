#pragma once
/// Registration of the back scan into the palm scan's frame (thesis §4.1.1), automatic.
/// register_scans runs these steps in order (registration.cpp), each a function of its own:
///   1. prepare_both        table and speckle removed, normals (prepare.cpp), both scans at once
///   2. settle_radius       the markers' radius estimated from the scans, unless it is given
///   3. find_both_markers   marker spheres in each scan (spheres.cpp), or at a hint file's places
///   4. match_checked       matching by distance pattern and the rigid fit of the centres
///                          (match.cpp); a match that cannot be trusted stops here
///   5. recover_missed      a marker found in one scan looked for where the pattern puts it
///   6. refine_checked      guarded refinement (refine.cpp), checked against the marker radius
///                          and the scanner's resolution
///   7. estimate_uncertainty  the fit's own error estimate (1σ)
///   8. merge_scans         one cloud in the palm frame, side labels, marker samples out
/// The result is typed (RegistrationDetail); registration.json is made from it in
/// pipeline/registration_stage.
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Geometry>
#include <functional>
#include <optional>
#include <string>
#include <vector>

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

/// One candidate radius tried: the bumps it found in each scan, and how many of them matched.
struct RadiusTry {
  double radius_mm = 0;
  size_t palm = 0, back = 0, matched = 0;
  /// false: not searched in the back scan, as its palm bumps were fewer than another
  /// candidate's matched markers (it could not win); back and matched are then 0.
  bool back_searched = true;
};

/// The markers' radius used: given, or estimated from the scans (registration.json
/// "marker_radius").
struct MarkerRadiusDetail {
  bool estimated = false;
  double radius_mm = 0;             ///< the radius used
  // Estimated only:
  std::vector<RadiusTry> tried;     ///< per candidate
  double candidate_mm = 0;          ///< the candidate radius that found the most markers
  int caps = 0;                     ///< caps (both scans) its estimate rests on
  double spread_mm = 0;             ///< median absolute deviation of their free fits
  std::vector<double> refinement_mm;  ///< the estimate, then each shared-radius refit
  double sd_mm = 0;                 ///< the last refit's standard deviation (0: not known)
  double free_fit_tolerance_mm = 0; ///< > 0: detections whose free fit strays further were dropped
};

/// One scan's part of the registration (registration.json "scans").
struct ScanRegistrationDetail {
  size_t returns = 0, table_points = 0, below_table = 0, speckle_points = 0, speckle_islands = 0, object_points = 0;
  Eigen::Vector4d table_plane = Eigen::Vector4d::Zero();  ///< n·p + d = 0, scan frame
  double table_tilt_deg = 0, table_rms_mm = 0;
  bool manual_markers = false;      ///< fitted at a hint file's positions (else detected)
  size_t candidates_examined = 0;   ///< detected: Hough candidates examined
  std::vector<SphereCandidateReport> rejected;  ///< detected: the first 20 rejected, with why
  size_t candidates_dropped = 0;    ///< detected: weakest left out beyond the expected count + 6
  std::vector<SphereFit> markers;   ///< the markers, scan frame (recovered ones appended)
  std::vector<int> partner;         ///< per marker: its match's index in the other scan, or -1
};

/// The matched centres' residuals after a fit: per pair (in match order), RMS and largest.
struct MarkerResiduals {
  std::vector<double> per_pair_mm;
  double rms_mm = 0, max_mm = 0;
};

/// The fit's own error estimate (1σ), when the joint marker fit's covariance could be made.
struct RegistrationUncertainty {
  bool valid = false;
  double rotation_deg = 0, displacement_mm = 0;
  double displacement_markers_mm = 0;  ///< the markers' share of the displacement
  double radius_mm = 0;                ///< the estimated radius's sd (0: given, or not known)
  double residual_sigma_mm = 0;
};

/// Everything registration.json tells (docs/formats.md), typed.
struct RegistrationDetail {
  RegistrationOptions used;          ///< the options as applied (spheres.radius_mm: the radius used)
  MarkerRadiusDetail radius;
  ScanRegistrationDetail back, palm;
  MarkerMatch match;                 ///< the matching, with the recovered markers' pairs
  int recovered = 0;                 ///< markers found in one scan where the pattern put them
  int left_out = 0;                  ///< matched pairs beyond expected_markers left out (a bump that is not a marker)
  MarkerResiduals marker_only, refined;  ///< at the marker-only and at the refined transform
  RefineResult refinement;
  double change_rotation_deg = 0, change_translation_mm = 0;  ///< refined against marker-only
  double accept_residual_mm = 0;     ///< the largest matched-centre disagreement allowed
  RegistrationUncertainty uncertainty;
  size_t merged_palm = 0, merged_back = 0, marker_samples_removed = 0;
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
  RegistrationDetail detail;                  ///< every detail (registration.json)
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

/// Binary PLY, atomically (x y z nx ny nz as float, label as uint: 0 = palm, 1 = back).
void save_merged(const std::string& path, const MergedCloud& cloud);
/// Read a merged cloud written by save_merged (through read_point_cloud: PLY, or PCD) as the
/// arrays the stages take. Throws InputError naming the file (and the point) when it cannot
/// be read, is empty, has no normals or no side labels, or holds a non-finite point or normal
/// or a side label other than 0 or 1.
MergedArrays read_merged(const std::string& path);

}  // namespace handskin
