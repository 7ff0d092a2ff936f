// Point clouds drawn as shaded round splats on the CPU: each point a disc, depth-tested, lit
// as the OpenGL pictures light their meshes (gl_render.cpp), 2 × supersampled and box-filtered
// the same way.
//
// Written here rather than drawn by Mesa: llvmpipe turns every smooth (round) point into
// triangles with a coverage shader, ~3 µs a point; a run's pictures hold about half a million
// of them (the merged cloud's 120 000, the two error views' measured points, the two layout
// views' 134 000 surface samples each), which took ~1.3 s of CPU, more than any stage. A disc
// of a few pixels with a depth test is a few lines: here the same pictures take ~15 ms each.
#include <cstdint>
#include <limits>

#include "core/errors.hpp"
#include "core/png_io.hpp"
#include "render/preview.hpp"
#include "render/raster.hpp"

namespace handskin {

std::string render_points_png(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& normals,
                              const std::vector<Eigen::Vector3f>& colours, const RenderOptions& o) {
  HS_CHECK(points.size() == normals.size() && points.size() == colours.size(), "point attributes differ in length");
  const raster::Framing f = raster::frame(o, points);
  constexpr int S = raster::kSupersample;
  const int W = o.width * S, H = o.height * S;
  // Splats about 0.5 mm across (at least 3 px), so a scan's sampling fills the surface.
  const double diameter = std::max(1.0, std::max(3.0, 1.0 * f.scale) * S);
  // Drawn a band of rows at a time: a band's colour and depth (~1 MB) instead of the whole
  // supersampled picture's (16 MB at 720 × 480, two such pictures drawn at once at the run's
  // peak of memory). Each band draws the splats that reach it in the points' order, so every
  // pixel sees the same splats in the same order as in one buffer: the same picture.
  constexpr int kBandRows = 32 * S;
  const int bands = (H + kBandRows - 1) / kBandRows;
  std::vector<std::vector<std::uint32_t>> in_band(static_cast<size_t>(bands));
  HS_CHECK(points.size() < std::numeric_limits<std::uint32_t>::max(), "too many points to draw");
  for (size_t k = 0; k < points.size(); ++k) {
    const auto [top, bottom] = raster::disc_rows(f.window(o.view * points[k]).y(), diameter);
    if (top > bottom || bottom < 0 || top > H - 1) continue;  // no row of the picture
    for (int b = std::max(0, top) / kBandRows; b <= std::min(H - 1, bottom) / kBandRows; ++b)
      in_band[b].push_back(static_cast<std::uint32_t>(k));
  }
  const raster::Lights lights;
  std::vector<std::uint8_t> rgba, rgb(static_cast<size_t>(o.width) * o.height * 3);
  std::vector<double> depth;
  for (int b = 0; b < bands; ++b) {
    const int row_lo = b * kBandRows, row_hi = std::min(H, row_lo + kBandRows);
    const size_t first = static_cast<size_t>(row_lo) * W, pixels = static_cast<size_t>(row_hi - row_lo) * W;
    raster::clear_to_background(&rgba, pixels);
    depth.assign(pixels, -std::numeric_limits<double>::infinity());
    for (const std::uint32_t k : in_band[b]) {
      const Eigen::Vector3d q = o.view * points[k];
      // Samples without a normal face the viewer.
      const Eigen::Vector3d n = normals[k].squaredNorm() > 0.5 ? Eigen::Vector3d((o.view * normals[k]).normalized())
                                                               : Eigen::Vector3d::UnitZ();
      const Eigen::Vector3d c = lights.shade(n, colours[k]);
      const std::uint8_t r = raster::byte_of(c.x()), g = raster::byte_of(c.y()), bl = raster::byte_of(c.z());
      const Eigen::Vector2d w = f.window(q);
      raster::disc(
          w.x(), w.y(), diameter, W, H,
          [&](size_t at) {
            at -= first;
            if (!(q.z() > depth[at])) return;  // nearer only: the first drawn keeps a tie
            depth[at] = q.z();
            rgba[4 * at] = r, rgba[4 * at + 1] = g, rgba[4 * at + 2] = bl;
          },
          row_lo, row_hi);
    }
    raster::draw_dots(o, f, W, H, &rgba, row_lo, row_hi);
    raster::downsample_rows(rgba.data(), o.width, row_lo / S, (row_hi - row_lo) / S, &rgb);
  }
  return encode_rgb8_png(o.width, o.height, rgb);
}

}  // namespace handskin
