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
