#pragma once
/// The synthetic CUBIST scanner: what a laser-triangulation range finder reports for a
/// scene of triangle meshes lying on its table.
///
/// Model: the camera looks straight down (-Z), one sample per (scanline i, point j);
/// the laser sheet is tilted by `laser_tilt_deg` from vertical toward +X, so a sample is
/// lit only if the ray toward the laser is free (shadows fall on the -X side of tall
/// parts); no return where the surface normal is steeper than `max_incidence_deg` to the
/// camera or to the laser; Gaussian depth noise, then quantisation to `z_step_mm`.
#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "scan/cubist_io.hpp"

namespace handskin {

struct ScannerOptions {
  int scanlines = 512;              ///< rows, X = const
  int points = 512;                 ///< samples per scanline, along Y
  double x_extent_mm = 250.0;       ///< table length covered by the scanlines
  double y_extent_mm = 200.0;       ///< table width covered by a scanline
  double z_extent_mm = 200.0;       ///< measuring height
  double z_step_mm = 0.2;           ///< depth quantisation
  double table_height_mm = 10.0;    ///< table top above the Z origin, at the table centre
  double table_tilt_deg = 0.0;      ///< table tilt about the scanner's Y axis
  double laser_tilt_deg = 20.0;     ///< laser sheet tilt from vertical, toward +X
  double max_incidence_deg = 72.0;  ///< steepest surface (to camera and laser) that returns
  double noise_sigma_mm = 0.05;     ///< Gaussian depth noise before quantisation
  bool IsValid(std::string* error) const;
  double x_step() const { return x_extent_mm / scanlines; }
  double y_step() const { return y_extent_mm / points; }
  double table_z(double x) const;   ///< table top height at scanner x
  Eigen::Vector3d laser_direction() const;  ///< unit, from a surface point toward the laser
};

/// Triangles in the scanner frame, each tagged with the object it belongs to (>= 0).
struct Scene {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::array<int, 3>> faces;
  std::vector<int> face_object;
  void add(const std::vector<Eigen::Vector3d>& v, const std::vector<std::array<int, 3>>& f, int object);
};

constexpr int kPixelNoReturn = -1;
constexpr int kPixelTable = -2;

struct ScanSimulation {
  RangeScan scan;
  std::vector<int> pixel_object;     ///< per pixel: object id, kPixelTable, or kPixelNoReturn
  std::vector<size_t> returns_per_object;
  /// What the camera sees at each pixel, lit or not (for the scan's photo): the scene face of
  /// the first hit above the table (−1: the table) and its height, mm.
  std::vector<int> camera_face;
  std::vector<float> camera_z;
  size_t shadowed = 0, too_steep = 0;
};

/// Scan `scene` from above. Deterministic for a given seed (noise drawn in pixel order).
ScanSimulation simulate_scan(const Scene& scene, const ScannerOptions& options, ScanSide side, std::uint64_t seed);

}  // namespace handskin
