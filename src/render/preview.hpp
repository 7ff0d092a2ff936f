#pragma once
/// Preview pictures (PNG) for people who would rather look than read: shaded meshes and lit
/// point splats drawn on the CPU (mesh_raster.cpp, splats.cpp), skeletons drawn by Mesa's
/// off-screen OpenGL (gl_render.cpp; no display or GPU needed), and a colour-coded range image.
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "core/texture_map.hpp"
#include "mesh/mesh.hpp"
#include "scan/cubist_io.hpp"

namespace handskin {

struct RenderOptions {
  int width = 800;
  int height = 600;
  /// Rotation applied before an orthographic view down -Z (camera frame: X right, Y up).
  Eigen::Matrix3d view = Eigen::Matrix3d::Identity();
  Eigen::Vector3f colour{0.87f, 0.72f, 0.62f};  ///< skin tone
  std::vector<Eigen::Vector3d> points;          ///< optional joints/markers drawn as dots
  /// Optional colour texture of the first mesh (its corner_uv one per face of that mesh):
  /// the colour is then (1 − texture_weight) · the shaded white surface + texture_weight ·
  /// the texture, as the thesis blended shading and photo 0.3 : 0.7.
  const TextureMap* texture = nullptr;
  float texture_weight = 0.7f;
};

/// Shaded orthographic render of one or more meshes (fit to the picture), on the CPU
/// (mesh_raster.cpp): depth-tested, lit per vertex as OpenGL's fixed function and smooth-shaded,
/// both sides lit, 2x supersampled. Returns PNG bytes.
std::string render_mesh_png(const std::vector<const Mesh*>& meshes, const RenderOptions& options);

/// Shaded splats of a point cloud with normals, one colour per point (fit to the picture):
/// discs about 0.5 mm across drawn on the CPU (splats.cpp), lit and framed as the meshes,
/// 2x supersampled. Returns PNG bytes.
std::string render_points_png(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& normals,
                              const std::vector<Eigen::Vector3f>& colours, const RenderOptions& options);

/// Skeletons as bones (lines from each joint to its parent) and joints (dots), one colour
/// each, fit to the picture together (e.g. the rest posture and a solved one).
struct SkeletonDrawing {
  std::vector<Eigen::Vector3d> joints;
  std::vector<int> parents;  ///< −1 for the root
  Eigen::Vector3f colour;
};
std::string render_skeletons_png(const std::vector<SkeletonDrawing>& skeletons, const RenderOptions& options);

/// A side view of any elongated flat object from its principal axes: the longest extent
/// runs right, the shortest up (for clouds without a rig, e.g. a merged scan pair).
Eigen::Matrix3d principal_view(const std::vector<Eigen::Vector3d>& points);

/// Height image of a scan: colour ramp over the measured heights, black for no return; rows
/// the scanlines, columns the points along them, drawn at the scan's own proportions (a row is
/// x_step_mm tall, a column y_step_mm wide). `width` px wide (0: one column a point), the
/// height to match; neither side over 4096 px (narrower then); each pixel the sample under
/// its centre.
std::string render_scan_png(const RangeScan& scan, int width = 0);

/// Standard views of the hand frame (X along the hand, Z out of the back): "back", "palm", "side".
Eigen::Matrix3d named_view(const std::string& name);

}  // namespace handskin
