#pragma once
/// Registration, step 3: which back marker is which palm marker, from the rigid-invariant
/// pattern of their pairwise distances alone, and the least-squares rigid fit of the pairs.
#include <Eigen/Geometry>
#include <utility>
#include <vector>

namespace handskin {

struct MarkerMatch {
  std::vector<std::pair<int, int>> pairs;  ///< (back index, palm index), by back index
  Eigen::Isometry3d back_to_palm = Eigen::Isometry3d::Identity();  ///< fit of the pairs
  double rms_mm = 0, max_mm = 0;           ///< centre residuals after the fit
  long hypotheses = 0;                     ///< triangle pairs that agreed in their distances
  /// The best matching that differs from the chosen one (empty if none): its pair count and
  /// residual say how clear-cut the choice was.
  size_t runner_up_pairs = 0;
  double runner_up_rms_mm = 0;
};

/// Rigid (proper rotation, det +1) least squares p_palm ≈ T·p_back over the given pairs
/// (Umeyama's SVD method, as PCL's TransformationEstimationSVD and Eigen::umeyama).
Eigen::Isometry3d fit_rigid(const std::vector<Eigen::Vector3d>& back, const std::vector<Eigen::Vector3d>& palm,
                            const std::vector<std::pair<int, int>>& pairs);

/// Match by congruent triangles: every triangle of back markers is tried against every
/// ordered triangle of palm markers whose side lengths agree within `tolerance_mm`; each
/// hypothesis is fitted, extended to every marker that lands within the tolerance, refitted,
/// and scored by pair count then residual. Robust to missing and spurious markers. A pair
/// set of fewer than 3 means no match.
MarkerMatch match_markers(const std::vector<Eigen::Vector3d>& back, const std::vector<Eigen::Vector3d>& palm,
                          double tolerance_mm);

}  // namespace handskin
