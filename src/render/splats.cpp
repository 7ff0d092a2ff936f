// Point clouds drawn as shaded round splats on the CPU: each point a disc, depth-tested, lit
// as the OpenGL pictures light their meshes (gl_render.cpp), 2 × supersampled and box-filtered
// the same way.
//
// Written here rather than drawn by Mesa: llvmpipe turns every smooth (round) point into
// triangles with a coverage shader, ~3 µs a point; a run's pictures hold about half a million
// of them (the merged cloud's 120 000, the two error views' measured points, the two layout
// views' 134 000 surface samples each), which took ~1.3 s of CPU, more than any stage. A disc
// of a few pixels with a depth test is a few lines: here the same pictures take ~15 ms each.
#include <limits>

#include "core/errors.hpp"
#include "render/preview.hpp"
#include "render/raster.hpp"

namespace handskin {

std::string render_points_png(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& normals,
                              const std::vector<Eigen::Vector3f>& colours, const RenderOptions& o) {
  HS_CHECK(points.size() == normals.size() && points.size() == colours.size(), "point attributes differ in length");
  const raster::Framing f = raster::frame(o, points);
  constexpr int S = raster::kSupersample;
  const int W = o.width * S, H = o.height * S;
  std::vector<std::uint8_t> rgba;
  raster::clear_to_background(&rgba, static_cast<size_t>(W) * H);
  std::vector<double> depth(static_cast<size_t>(W) * H, -std::numeric_limits<double>::infinity());
  // Splats about 0.5 mm across (at least 3 px), so a scan's sampling fills the surface.
  const double diameter = std::max(1.0, std::max(3.0, 1.0 * f.scale) * S);
  const raster::Lights lights;
  for (size_t k = 0; k < points.size(); ++k) {
    const Eigen::Vector3d q = o.view * points[k];
    // Samples without a normal face the viewer.
    const Eigen::Vector3d n = normals[k].squaredNorm() > 0.5 ? Eigen::Vector3d((o.view * normals[k]).normalized())
                                                             : Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d c = lights.shade(n, colours[k]);
    const std::uint8_t r = raster::byte_of(c.x()), g = raster::byte_of(c.y()), b = raster::byte_of(c.z());
    const Eigen::Vector2d w = f.window(q);
    raster::disc(w.x(), w.y(), diameter, W, H, [&](size_t at) {
      if (!(q.z() > depth[at])) return;  // nearer only: the first drawn keeps a tie
      depth[at] = q.z();
      rgba[4 * at] = r, rgba[4 * at + 1] = g, rgba[4 * at + 2] = b;
    });
  }
  raster::draw_dots(o, f, W, H, &rgba);
  return raster::downsample_png(rgba, o.width, o.height);
}

}  // namespace handskin
