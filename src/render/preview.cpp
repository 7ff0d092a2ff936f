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
  throw InputError("--view", "unknown view '" + name + "' (use back, palm or side)");
}

namespace {

// An orthographic picture fitted to a set of view-space points, with a depth buffer.
class Canvas {
 public:
  Canvas(const RenderOptions& o, const std::vector<Eigen::Vector3d>& view_points) : o_(o) {
    HS_CHECK(o.width > 0 && o.height > 0, "empty picture");
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e18), hi = -lo;
    for (const auto& q : view_points) {
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
    HS_CHECK(hi.x() >= lo.x(), "nothing to render");
    scale_ = 0.92 * std::min(o.width / std::max(hi.x() - lo.x(), 1e-9), o.height / std::max(hi.y() - lo.y(), 1e-9));
    centre_ = 0.5 * (lo + hi).head<2>();
    depth_.assign(static_cast<size_t>(o.width) * o.height, -std::numeric_limits<float>::infinity());
    rgb_.resize(static_cast<size_t>(o.width) * o.height * 3);
    for (size_t k = 0; k < rgb_.size(); k += 3) rgb_[k] = 246, rgb_[k + 1] = 246, rgb_[k + 2] = 248;
  }
  /// View-space point -> pixel coordinates (x right, y down) and depth.
  Eigen::Vector3d to_px(const Eigen::Vector3d& q) const {
    return {o_.width / 2.0 + (q.x() - centre_.x()) * scale_, o_.height / 2.0 - (q.y() - centre_.y()) * scale_, q.z()};
  }
  double scale() const { return scale_; }
  /// Shade a pixel if it is nearer than what is there.
  void plot(int x, int y, double z, Eigen::Vector3d n, const Eigen::Vector3f& colour) {
    if (x < 0 || y < 0 || x >= o_.width || y >= o_.height) return;
    const size_t idx = static_cast<size_t>(y) * o_.width + x;
    if (z <= depth_[idx]) return;
    depth_[idx] = static_cast<float>(z);
    if (n.z() < 0) n = -n;
    const double shade = 0.22 + 0.63 * std::max(0.0, n.dot(light_)) + 0.3 * std::max(0.0, n.dot(fill_));
    for (int c = 0; c < 3; ++c)
      rgb_[idx * 3 + c] = static_cast<std::uint8_t>(std::clamp(255.0 * colour[c] * shade, 0.0, 255.0));
  }
  /// Red dots (joints, markers) drawn over everything.
  void dots(const std::vector<Eigen::Vector3d>& points) {
    for (const auto& p : points) {
      const Eigen::Vector3d q = to_px(o_.view * p);
      for (int dy = -3; dy <= 3; ++dy)
        for (int dx = -3; dx <= 3; ++dx) {
          const int x = static_cast<int>(q.x()) + dx, y = static_cast<int>(q.y()) + dy;
          if (x < 0 || y < 0 || x >= o_.width || y >= o_.height || dx * dx + dy * dy > 9) continue;
          const size_t idx = static_cast<size_t>(y) * o_.width + x;
          rgb_[idx * 3] = 200, rgb_[idx * 3 + 1] = 30, rgb_[idx * 3 + 2] = 40;
        }
    }
  }
  /// A flat-coloured disc of radius r pixels (no shading), depth-tested.
  void disc(double cx, double cy, double z, double r, const Eigen::Vector3f& colour) {
    const int reach = static_cast<int>(std::ceil(r));
    for (int dy = -reach; dy <= reach; ++dy)
      for (int dx = -reach; dx <= reach; ++dx) {
        if (dx * dx + dy * dy > r * r) continue;
        const int x = static_cast<int>(cx) + dx, y = static_cast<int>(cy) + dy;
        if (x < 0 || y < 0 || x >= o_.width || y >= o_.height) continue;
        const size_t idx = static_cast<size_t>(y) * o_.width + x;
        if (z <= depth_[idx]) continue;
        depth_[idx] = static_cast<float>(z);
        for (int c = 0; c < 3; ++c) rgb_[idx * 3 + c] = static_cast<std::uint8_t>(std::clamp(255.0 * colour[c], 0.0, 255.0));
      }
  }
  std::string png() const { return encode_rgb8_png(o_.width, o_.height, rgb_); }

 private:
  const RenderOptions& o_;
  double scale_ = 1;
  Eigen::Vector2d centre_;
  std::vector<float> depth_;
  std::vector<std::uint8_t> rgb_;
  const Eigen::Vector3d light_ = Eigen::Vector3d(-0.4, 0.5, 1.0).normalized();  // key, from upper left
  const Eigen::Vector3d fill_ = Eigen::Vector3d(0.3, -0.7, 0.65).normalized();   // fill, from below
};

}  // namespace

std::string render_points_png(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& normals,
                              const std::vector<Eigen::Vector3f>& colours, const RenderOptions& o) {
  HS_CHECK(points.size() == normals.size() && points.size() == colours.size(), "point attributes differ in length");
  std::vector<Eigen::Vector3d> vp;
  vp.reserve(points.size());
  for (const auto& p : points) vp.push_back(o.view * p);
  Canvas canvas(o, vp);
  // Splats about 0.5 mm across (at least 1.5 px), so a scan's sampling fills the surface.
  const double rad = std::max(1.5, 0.5 * canvas.scale());
  const int reach = static_cast<int>(std::ceil(rad));
  for (size_t k = 0; k < points.size(); ++k) {
    const Eigen::Vector3d q = canvas.to_px(vp[k]);
    // Samples without a normal face the viewer.
    const Eigen::Vector3d n = normals[k].squaredNorm() > 0.5 ? Eigen::Vector3d(o.view * normals[k]) : Eigen::Vector3d::UnitZ();
    for (int dy = -reach; dy <= reach; ++dy)
      for (int dx = -reach; dx <= reach; ++dx)
        if (dx * dx + dy * dy <= rad * rad)
          canvas.plot(static_cast<int>(q.x()) + dx, static_cast<int>(q.y()) + dy, q.z(), n, colours[k]);
  }
  canvas.dots(o.points);
  return canvas.png();
}

std::string render_skeletons_png(const std::vector<SkeletonDrawing>& skeletons, const RenderOptions& o) {
  std::vector<Eigen::Vector3d> vp;
  for (const auto& sk : skeletons)
    for (const auto& p : sk.joints) vp.push_back(o.view * p);
  HS_CHECK(!vp.empty(), "no joints to draw");
  Canvas canvas(o, vp);
  for (const auto& sk : skeletons) {
    HS_CHECK(sk.joints.size() == sk.parents.size(), "joints and parents differ in length");
    for (size_t j = 0; j < sk.joints.size(); ++j) {
      const Eigen::Vector3d a = canvas.to_px(o.view * sk.joints[j]);
      canvas.disc(a.x(), a.y(), a.z() + 0.01, 4.0, sk.colour);
      if (sk.parents[j] < 0) continue;
      const Eigen::Vector3d b = canvas.to_px(o.view * sk.joints[sk.parents[j]]);
      const int steps = static_cast<int>(std::ceil((a - b).head<2>().norm())) + 1;
      for (int k = 0; k <= steps; ++k) {
        const Eigen::Vector3d q = b + (a - b) * (static_cast<double>(k) / steps);
        canvas.disc(q.x(), q.y(), q.z(), 1.6, sk.colour);
      }
    }
  }
  return canvas.png();
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

std::string render_scan_png(const RangeScan& scan) {
  const int w = scan.meta.points, h = scan.meta.scanlines;
  std::uint16_t lo = 65535, hi = 0;
  for (std::uint16_t v : scan.values)
    if (v) lo = std::min(lo, v), hi = std::max(hi, v);
  std::vector<std::uint8_t> rgb(static_cast<size_t>(w) * h * 3, 0);
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      const std::uint16_t v = scan.at(i, j);
      if (!v) continue;
      const double t = hi > lo ? static_cast<double>(v - lo) / (hi - lo) : 0.5;
      // Blue (low) -> yellow (high) ramp, gamma-lifted so low relief stays visible.
      const double g = std::pow(t, 0.6);
      const size_t idx = (static_cast<size_t>(i) * w + j) * 3;
      rgb[idx] = static_cast<std::uint8_t>(40 + 215 * g);
      rgb[idx + 1] = static_cast<std::uint8_t>(60 + 170 * g);
      rgb[idx + 2] = static_cast<std::uint8_t>(140 - 100 * g);
    }
  return encode_rgb8_png(w, h, rgb);
}

}  // namespace handskin
