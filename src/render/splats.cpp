// Point clouds drawn as shaded round splats on the CPU: each point a disc, depth-tested, lit
// as the OpenGL pictures light their meshes (gl_render.cpp), 2 × supersampled and box-filtered
// the same way.
//
// Written here rather than drawn by Mesa: llvmpipe turns every smooth (round) point into
// triangles with a coverage shader, ~3 µs a point; a run's pictures hold about half a million
// of them (the merged cloud's 120 000, the two error views' measured points, the two layout
// views' 134 000 surface samples each), which took ~1.3 s of CPU, more than any stage. A disc
// of a few pixels with a depth test is a few lines: here the same pictures take ~15 ms each.
#include <algorithm>
#include <cmath>
#include <limits>

#include "core/errors.hpp"
#include "render/preview.hpp"
#include "render/raster.hpp"

namespace handskin {

namespace {

// OpenGL's fixed-function lighting of the lights gl_render.cpp sets up (raster::light), for a
// point (always lit from the front): the colour is the material's ambient and diffuse.
struct Lights {
  Eigen::Vector3d key = Eigen::Vector3d(raster::light::kKey).normalized();
  Eigen::Vector3d fill = Eigen::Vector3d(raster::light::kFill).normalized();
  Eigen::Vector3d half = (key + Eigen::Vector3d::UnitZ()).normalized();
  Eigen::Vector3d shade(const Eigen::Vector3d& n, const Eigen::Vector3f& c) const {
    namespace L = raster::light;
    const double k = n.dot(key), f = std::max(0.0, n.dot(fill));
    const double diffuse = L::kAmbient + L::kKeyColour * std::max(0.0, k) + L::kFillColour * f;
    const double spec = k > 0 ? L::kKeyColour * L::kSpecular * std::pow(std::max(0.0, n.dot(half)), L::kShininess) : 0.0;
    return (diffuse * c.cast<double>().array() + spec).min(1.0).matrix();
  }
};

std::uint8_t byte_of(double v) { return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255)); }

// A disc of `diameter` supersampled pixels at window position (x, y) (pixels from the top
// left): the pixels whose centres lie inside it.
template <typename Put>
void disc(double x, double y, double diameter, int W, int H, Put put) {
  const double r = 0.5 * diameter, r2 = r * r;
  const int y0 = std::max(0, static_cast<int>(std::ceil(y - r - 0.5))), y1 = std::min(H - 1, static_cast<int>(std::floor(y + r - 0.5)));
  const int x0 = std::max(0, static_cast<int>(std::ceil(x - r - 0.5))), x1 = std::min(W - 1, static_cast<int>(std::floor(x + r - 0.5)));
  for (int j = y0; j <= y1; ++j) {
    const double dy = j + 0.5 - y;
    for (int i = x0; i <= x1; ++i) {
      const double dx = i + 0.5 - x;
      if (dx * dx + dy * dy <= r2) put(static_cast<size_t>(j) * W + i);
    }
  }
}

}  // namespace

std::string render_points_png(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& normals,
                              const std::vector<Eigen::Vector3f>& colours, const RenderOptions& o) {
  HS_CHECK(points.size() == normals.size() && points.size() == colours.size(), "point attributes differ in length");
  const raster::Framing f = raster::frame(o, points);
  constexpr int S = raster::kSupersample;
  const int W = o.width * S, H = o.height * S;
  std::vector<std::uint8_t> rgba(static_cast<size_t>(W) * H * 4);
  for (size_t k = 0; k < rgba.size(); k += 4)
    rgba[k] = raster::kBackground[0], rgba[k + 1] = raster::kBackground[1], rgba[k + 2] = raster::kBackground[2], rgba[k + 3] = 255;
  std::vector<double> depth(static_cast<size_t>(W) * H, -std::numeric_limits<double>::infinity());
  const double px = W / (2 * f.half_w);  // supersampled pixels per mm
  const auto window = [&](const Eigen::Vector3d& q, double* x, double* y) {
    *x = (q.x() - (f.centre.x() - f.half_w)) * px;
    *y = ((f.centre.y() + f.half_h) - q.y()) * px;
  };
  // Splats about 0.5 mm across (at least 3 px), so a scan's sampling fills the surface.
  const double diameter = std::max(1.0, std::max(3.0, 1.0 * f.scale) * S);
  const Lights lights;
  for (size_t k = 0; k < points.size(); ++k) {
    const Eigen::Vector3d q = o.view * points[k];
    // Samples without a normal face the viewer.
    const Eigen::Vector3d n = normals[k].squaredNorm() > 0.5 ? Eigen::Vector3d((o.view * normals[k]).normalized())
                                                             : Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d c = lights.shade(n, colours[k]);
    const std::uint8_t r = byte_of(c.x()), g = byte_of(c.y()), b = byte_of(c.z());
    double x, y;
    window(q, &x, &y);
    disc(x, y, diameter, W, H, [&](size_t at) {
      if (!(q.z() > depth[at])) return;  // nearer only: the first drawn keeps a tie
      depth[at] = q.z();
      rgba[4 * at] = r, rgba[4 * at + 1] = g, rgba[4 * at + 2] = b;
    });
  }
  // Joints or markers: red dots over everything.
  for (const auto& p : o.points) {
    double x, y;
    window(o.view * p, &x, &y);
    disc(x, y, raster::kDotPx * S, W, H, [&](size_t at) {
      for (int c = 0; c < 3; ++c) rgba[4 * at + c] = raster::kDotColour[c];
    });
  }
  return raster::downsample_png(rgba, o.width, o.height);
}

}  // namespace handskin
