#pragma once
/// Registration, step 1: from a range scan to the object's points with normals — the table
/// plane removed (PCL RANSAC), isolated speckle dropped, a normal per point from the height field.
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "scan/cubist_io.hpp"

namespace handskin {

struct PrepareOptions {
  double table_margin_mm = 1.0;     ///< points lower than this above the table plane are table
  double table_max_tilt_deg = 10.0; ///< the table plane's normal is within this of the scanner's Z
  double table_inlier_mm = 0.5;     ///< RANSAC inlier distance for the table plane
  /// Smaller pixel-connected islands above the table are speckle. Small: a marker on a steep
  /// flank often returns as an island of its own (the junction ring is too steep to return).
  long min_component_points = 8;
  int normal_window = 2;            ///< normals from a (2w+1)² window of the height field
  bool IsValid(std::string* error) const;
};

/// The object's points of one scan, in the scanner frame (mm).
struct PreparedScan {
  ScanSide side = ScanSide::Back;
  int rows = 0, cols = 0;           ///< the scan's grid
  double x_origin = 0, y_origin = 0;
  double x_step = 0, y_step = 0, z_step = 0;
  std::vector<int> point_of_pixel;  ///< per pixel: index into `points`, or -1
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector3d> normals;   ///< unit, toward the camera (+Z side); zero if unknown
  std::vector<int> pixel;                 ///< per point: i * cols + j
  Eigen::Vector4d table_plane = Eigen::Vector4d::Zero();  ///< n·p + d = 0, n upward, |n| = 1
  double table_tilt_deg = 0, table_rms_mm = 0;
  size_t returns = 0, table_points = 0, below_table = 0, speckle_points = 0, speckle_islands = 0;
  bool has_normal(size_t k) const { return normals[k].squaredNorm() > 0.5; }
};

/// Remove the table and speckle and estimate normals. `file` names the scan in errors
/// (no table plane found, nothing left above the table).
PreparedScan prepare_scan(const RangeScan& scan, const PrepareOptions& options, const std::string& file);

/// Normals of a height field by a least-squares plane z = a + b·dx + c·dy over a window of
/// kept pixels whose height is within `max_step_mm` of the centre's (so a window straddling
/// a depth jump does not bend the normal). Exposed for tests.
void height_field_normals(PreparedScan* s, int window, double max_step_mm);

}  // namespace handskin
