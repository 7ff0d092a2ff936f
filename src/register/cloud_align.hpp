#pragma once
/// Two partial clouds of one hand (e.g. a scanner's back views and its palm views), each in a
/// pose of its own, registered without markers (issue 37). align_halves runs these steps:
///   1. frames        each half's principal axes and centroid, on a 2.5 mm voxel grid
///   2. candidates    the rotations that map one half's axes onto the other's (four, the
///                    long axis either way) and offsets along the thickness axis (a back
///                    shell's centroid lies above a palm shell's)
///   3. coarse        each candidate refined by point-to-plane ICP on the coarse grids with a
///                    shrinking correspondence distance; kept: the one whose halves meet over
///                    the most of the first (the flanks both saw) per mm of residual
///   4. fine          point-to-plane ICP on the full clouds, correspondences within 1 mm
///   5. uncertainty   the fit's own 1σ from the point-to-plane residuals and their Jacobian
/// Markers are not used. The halves must overlap (flanks seen from both sides); the same
/// half twice (overlap over 80 %) is refused.
#include <Eigen/Geometry>
#include <string>
#include <utility>
#include <vector>

namespace handskin {

struct CloudAlignOptions {
  double coarse_voxel_mm = 2.5;
  double overlap_mm = 1.0;          ///< a point of the first half meets the second within this
  double same_half_share = 0.8;     ///< overlap over this: the same half twice
  double min_overlap_share = 0.05;  ///< under this: the halves do not meet
};

struct CloudAlignment {
  Eigen::Isometry3d a_to_b = Eigen::Isometry3d::Identity();  ///< p_b = a_to_b · p_a
  int candidates = 0;               ///< starts tried
  double overlap_share = 0;         ///< of the first half's points, within overlap_mm of the second
  double rms_mm = 0;                ///< point-to-plane residual over the overlap
  double rotation_sigma_deg = 0, displacement_sigma_mm = 0;  ///< the fit's own 1σ
  std::vector<std::pair<std::string, double>> timings_ms;
};

/// Register half `a` into half `b` (points and unoriented normals, mm; both cleaned by
/// prepare_cloud). `a_file`, `b_file` name them in errors. Throws InputError when the halves
/// do not meet, or are the same half.
CloudAlignment align_halves(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
                            const std::vector<Eigen::Vector3d>& b_normals, const std::string& a_file,
                            const std::string& b_file, const CloudAlignOptions& options);

}  // namespace handskin
