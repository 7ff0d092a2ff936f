#pragma once
// What the pictures drawn on the CPU (splats.cpp, mesh_raster.cpp) and by OpenGL
// (gl_render.cpp) share: the orthographic framing of a picture, the lights, and the
// supersampled buffer filtered down to PNG.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "render/preview.hpp"

namespace handskin::raster {

constexpr int kSupersample = 2;  ///< pictures are drawn at 2 × their size and box-filtered down: smooth edges

/// The lights, material and colours every picture shares: gl_render sets them in OpenGL
/// (as floats), splats applies OpenGL's fixed-function formula to them. Directional lights in
/// view space, the viewer at infinity: a key from the upper left (diffuse and specular), a fill
/// from below (diffuse), the scene's ambient; the material's specular and shininess.
namespace light {
constexpr double kKey[3] = {-0.4, 0.5, 1.0}, kFill[3] = {0.3, -0.7, 0.65};
constexpr double kKeyColour = 0.63, kFillColour = 0.3, kAmbient = 0.22, kSpecular = 0.12, kShininess = 24;
}  // namespace light
constexpr std::uint8_t kBackground[3] = {246, 246, 248};  ///< the pictures' background
constexpr std::uint8_t kDotColour[3] = {200, 30, 40};     ///< joints and markers, over everything
constexpr double kDotPx = 7;                               ///< their diameter, output pixels

/// OpenGL's fixed-function lighting (the viewer at infinity) of the lights above, for a
/// view-space unit normal facing the viewer's side and a material whose ambient and diffuse
/// colour is `c`: the colour, clamped to 1 as OpenGL clamps a vertex's.
struct Lights {
  Eigen::Vector3d key = Eigen::Vector3d(light::kKey).normalized();
  Eigen::Vector3d fill = Eigen::Vector3d(light::kFill).normalized();
  Eigen::Vector3d half = (key + Eigen::Vector3d::UnitZ()).normalized();
  Eigen::Vector3d shade(const Eigen::Vector3d& n, const Eigen::Vector3f& c) const {
    const double k = n.dot(key), f = std::max(0.0, n.dot(fill));
    const double diffuse = light::kAmbient + light::kKeyColour * std::max(0.0, k) + light::kFillColour * f;
    const double spec = k > 0 ? light::kKeyColour * light::kSpecular * std::pow(std::max(0.0, n.dot(half)), light::kShininess) : 0.0;
    return (diffuse * c.cast<double>().array() + spec).min(1.0).matrix();
  }
};

/// A colour in [0, 1] as a byte, rounded as OpenGL stores it: to nearest, halves up, as
/// std::lround, inline (libm's lround was ~5 % of a picture's time, called for every channel
/// of every fragment). x − ⌊x⌋ is exact for x in [0, 255] (Sterbenz), so the bytes are lround's.
inline std::uint8_t byte_of(double v) {
  const double x = std::clamp(v, 0.0, 1.0) * 255;
  if (!(x >= 0 && x <= 255)) return static_cast<std::uint8_t>(std::lround(x));  // NaN: as lround has it
  const int r = static_cast<int>(x);
  return static_cast<std::uint8_t>(r + (x - r >= 0.5 ? 1 : 0));
}

/// The rows a disc of `diameter` supersampled pixels centred at window row y covers, first and
/// last, unclipped: the pixel rows whose centres lie within its radius of y.
inline std::pair<int, int> disc_rows(double y, double diameter) {
  const double r = 0.5 * diameter;
  return {static_cast<int>(std::ceil(y - r - 0.5)), static_cast<int>(std::floor(y + r - 0.5))};
}

/// A disc of `diameter` supersampled pixels at window position (x, y) (pixels from the top
/// left): `put` is called with the index (row × W + column) of every pixel whose centre lies
/// inside it, in rows [row_lo, row_hi) of the H rows (a band of the picture; all by default).
template <typename Put>
void disc(double x, double y, double diameter, int W, int H, Put put, int row_lo = 0, int row_hi = -1) {
  const double r = 0.5 * diameter, r2 = r * r;
  const auto [top, bottom] = disc_rows(y, diameter);
  const int y0 = std::max({0, row_lo, top}), y1 = std::min({H - 1, (row_hi < 0 ? H : row_hi) - 1, bottom});
  const int x0 = std::max(0, static_cast<int>(std::ceil(x - r - 0.5))), x1 = std::min(W - 1, static_cast<int>(std::floor(x + r - 0.5)));
  for (int j = y0; j <= y1; ++j) {
    const double dy = j + 0.5 - y;
    for (int i = x0; i <= x1; ++i) {
      const double dx = i + 0.5 - x;
      if (dx * dx + dy * dy <= r2) put(static_cast<size_t>(j) * W + i);
    }
  }
}

/// The view-space box of the points (o.view applied), fitted to 92 % of the frame.
struct Framing {
  Eigen::Vector3d lo, hi, centre;  ///< view-space bounds and their middle
  double scale = 1;                ///< output pixels per mm
  double half_w = 1, half_h = 1;   ///< the frame's half extents, mm
  double px = 1;                   ///< supersampled pixels per mm
  /// A view-space point's window position in the supersampled buffer: x right, y down, pixels.
  Eigen::Vector2d window(const Eigen::Vector3d& q) const {
    return {(q.x() - (centre.x() - half_w)) * px, ((centre.y() + half_h) - q.y()) * px};
  }
};
Framing frame(const RenderOptions& o, const std::vector<Eigen::Vector3d>& model_points);

/// Joints or markers (`o.points`): red dots over everything in the W × H supersampled buffer,
/// or in its band of rows [row_lo, row_hi) when `rgba` holds only those rows.
inline void draw_dots(const RenderOptions& o, const Framing& f, int W, int H, std::vector<std::uint8_t>* rgba, int row_lo = 0,
                      int row_hi = -1) {
  const size_t first = static_cast<size_t>(row_lo) * W;
  for (const auto& p : o.points) {
    const Eigen::Vector2d w = f.window(o.view * p);
    disc(
        w.x(), w.y(), kDotPx * kSupersample, W, H,
        [&](size_t at) {
          for (int c = 0; c < 3; ++c) (*rgba)[4 * (at - first) + c] = kDotColour[c];
        },
        row_lo, row_hi);
  }
}

/// A supersampled RGBA buffer of `pixels` pixels, every one the background, opaque.
inline void clear_to_background(std::vector<std::uint8_t>* rgba, size_t pixels) {
  rgba->resize(4 * pixels);
  for (size_t k = 0; k < rgba->size(); k += 4)
    (*rgba)[k] = kBackground[0], (*rgba)[k + 1] = kBackground[1], (*rgba)[k + 2] = kBackground[2], (*rgba)[k + 3] = 255;
}

/// A kSupersample × larger RGBA buffer (row 0 at the top) box-filtered to width × height, as PNG.
std::string downsample_png(const std::vector<std::uint8_t>& rgba, int width, int height);

/// Rows [row, row + rows) of a width × height RGB picture box-filtered from `band`: the
/// kSupersample × larger RGBA buffer's rows from row × kSupersample on (row 0 at the top).
void downsample_rows(const std::uint8_t* band, int width, int row, int rows, std::vector<std::uint8_t>* rgb);

}  // namespace handskin::raster
