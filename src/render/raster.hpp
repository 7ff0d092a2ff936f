#pragma once
// What the OpenGL pictures (gl_render.cpp) and the CPU splats (splats.cpp) share: the
// orthographic framing of a picture and its supersampled buffer filtered down to PNG.
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "render/preview.hpp"

namespace handskin::raster {

constexpr int kSupersample = 2;  ///< pictures are drawn at 2 × their size and box-filtered down: smooth edges

/// The view-space box of the points (o.view applied), fitted to 92 % of the frame.
struct Framing {
  Eigen::Vector3d lo, hi, centre;  ///< view-space bounds and their middle
  double scale = 1;                ///< output pixels per mm
  double half_w = 1, half_h = 1;   ///< the frame's half extents, mm
};
Framing frame(const RenderOptions& o, const std::vector<Eigen::Vector3d>& model_points);

/// A kSupersample × larger RGBA buffer (row 0 at the top) box-filtered to width × height, as PNG.
std::string downsample_png(const std::vector<std::uint8_t>& rgba, int width, int height);

}  // namespace handskin::raster
