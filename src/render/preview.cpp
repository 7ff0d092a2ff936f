#include "render/preview.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/errors.hpp"
#include "core/png_io.hpp"

namespace handskin {

Eigen::Matrix3d named_view(const std::string& name) {
  using Eigen::AngleAxisd;
  using Eigen::Vector3d;
  // Hand lies along +X; show it with the fingers up the picture.
  const Eigen::Matrix3d up = AngleAxisd(M_PI / 2, Vector3d::UnitZ()).toRotationMatrix();
  if (name == "back") return up;
  if (name == "palm") return AngleAxisd(M_PI, Vector3d::UnitY()).toRotationMatrix() * up;
  if (name == "side") {  // from the thumb side, fingers to the left, back of the hand up
    Eigen::Matrix3d R;
    R << -1, 0, 0, 0, 0, 1, 0, 1, 0;
    return R;
  }
  throw UsageError("--view", "unknown view '" + name + "' (use back, palm or side)");
}


Eigen::Matrix3d principal_view(const std::vector<Eigen::Vector3d>& points) {
  HS_CHECK(!points.empty(), "no points");
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : points) cov += (p - mean) * (p - mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  // Longest extent to the right, shortest (the hand's thickness) up: a side view.
  Eigen::Matrix3d R;
  R.row(0) = es.eigenvectors().col(2).transpose();
  R.row(1) = es.eigenvectors().col(0).transpose();
  R.row(2) = R.row(0).cross(R.row(1));
  return R;
}

std::string render_scan_png(const RangeScan& scan, int width) {
  // At the scan's proportions: CUBIST's rows are 250/512 mm apart, its columns 200/512 mm, so
  // one pixel a sample drew the hand 20 % short along its scanlines' direction; a scan with
  // half the points a line, twice as far apart, came out half as wide as it is (before
  // 2026-11-30).
  const int points = scan.meta.points, lines = scan.meta.scanlines;
  const double aspect = (lines * scan.meta.x_step_mm) / (points * scan.meta.y_step_mm);
  int w = width > 0 ? width : points;
  // Neither side over 4096 px (a long, narrow scan at --size 4096 would otherwise ask for
  // hundreds of megabytes): the picture is made smaller, its proportions kept.
  constexpr double kMaxSide = 4096;
  if (w * aspect > kMaxSide) w = std::max(1, static_cast<int>(kMaxSide / aspect));
  const int h = std::clamp(static_cast<int>(std::lround(w * aspect)), 1, static_cast<int>(kMaxSide));
  std::uint16_t lo = 65535, hi = 0;
  for (std::uint16_t v : scan.values)
    if (v) lo = std::min(lo, v), hi = std::max(hi, v);
  std::vector<std::uint8_t> rgb(static_cast<size_t>(w) * h * 3, 0);
  for (int r = 0; r < h; ++r) {
    const int i = std::min(lines - 1, static_cast<int>((r + 0.5) * lines / h));
    for (int c = 0; c < w; ++c) {
      const int j = std::min(points - 1, static_cast<int>((c + 0.5) * points / w));
      const std::uint16_t v = scan.at(i, j);
      if (!v) continue;
      const double t = hi > lo ? static_cast<double>(v - lo) / (hi - lo) : 0.5;
      // Blue (low) -> yellow (high) ramp, gamma-lifted so low relief stays visible.
      const double g = std::pow(t, 0.6);
      const size_t idx = (static_cast<size_t>(r) * w + c) * 3;
      rgb[idx] = static_cast<std::uint8_t>(40 + 215 * g);
      rgb[idx + 1] = static_cast<std::uint8_t>(60 + 170 * g);
      rgb[idx + 2] = static_cast<std::uint8_t>(140 - 100 * g);
    }
  }
  return encode_rgb8_png(w, h, rgb);
}

}  // namespace handskin
