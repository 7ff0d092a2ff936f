#pragma once
/// The skin's colour from the two scans' photos (thesis §4.1.5; docs/rigging.md "Texture").
///
/// The thesis projected a palm photo and a back photo onto the model's X–Y plane and blurred
/// their border by hand. Here each photo is the scan's own camera image on its range image's
/// grid (`<stem>.photo.png`), so it projects along that scan's view through the registration:
/// - a skin point takes its colour from the scans whose camera sees it — facing the camera
///   (softly: a smoothstep over ± `blend_deg` of the normal's angle to the view's horizon, so
///   the two photos blend across the flanks), not hidden by another part of the skin (a ray
///   toward the camera), and not behind a marker sphere;
/// - the texture atlas has two charts: faces that face the palm camera more are projected
///   onto the palm scan's X–Y plane (the model's), the others onto the back scan's; faces
///   that neither camera sees take a small block of the mean skin colour;
/// - texels that no photo covers (under the markers) are filled from their neighbours, and each
///   chart is padded so that filtering never reaches the background.
#include <Eigen/Geometry>
#include <array>
#include <string>
#include <vector>

#include "core/png_io.hpp"
#include "core/texture_map.hpp"
#include "scan/cubist_io.hpp"

namespace handskin {

/// A scan's photo: 8-bit RGB, one pixel per range sample (row i = scanline i, column j =
/// point j), so it shares the scan's grid, with the scan itself: a photo pixel is used for a
/// skin point only where the range image measured that point's height there (±
/// `kPhotoDepthToleranceMm` in texture.cpp) — not the table beside the silhouette, not a
/// marker, not another part of the hand.
struct ScanPhoto {
  Rgb8Image image;
  RangeScan scan;
};

/// Read `file` as the photo of `scan`. Throws InputError naming the file when it is not an
/// 8-bit RGB(A) PNG or its size is not the scan's points × scanlines.
ScanPhoto load_scan_photo(const std::string& file, const RangeScan& scan);

struct TextureOptions {
  int size = 1024;         ///< the atlas is size × size texels
  double blend_deg = 15;   ///< the photos blend over ± this angle of the normal about each view's horizon
  bool IsValid(std::string* error) const;
};

struct SkinTexture {
  TextureMap map;
  /// Share of the skin's area coloured by the palm photo alone, the back photo alone, both
  /// (blended across the flanks), and neither (hidden from both cameras or under a marker:
  /// filled from neighbours or the mean colour).
  double palm_only = 0, back_only = 0, blended = 0, unseen = 0;
  size_t palm_chart_faces = 0, back_chart_faces = 0, unseen_faces = 0;
  double texels_per_mm = 0;  ///< the atlas's resolution on the skin (both charts alike)
  double seconds = 0;
};

/// Bake the texture of the skin (`vertices`, `faces`: palm frame, mm, outward) from the two
/// photos. `markers` (palm frame) of `marker_radius_mm` hide the skin behind them. The steps
/// (texture.cpp, `Baker`):
///   1. visibility      vertex normals, and whether each camera sees each vertex (a ray toward it)
///   2. choose_charts   each face to the camera it faces more, among those that see it whole
///   3. lay_out_charts  each chart projected on its scan's plane, one scale for both
///   4. bake_faces      per texel of each chart face, the photos' colours weighted by how
///                      squarely each camera sees it; the area shares
///   5. fill            unseen chart texels from their neighbours, then the charts padded
SkinTexture bake_skin_texture(const std::vector<Eigen::Vector3d>& vertices, const std::vector<std::array<int, 3>>& faces,
                              const ScanPhoto& back, const ScanPhoto& palm, const Eigen::Isometry3d& back_to_palm,
                              const std::vector<Eigen::Vector3d>& markers, double marker_radius_mm,
                              const TextureOptions& options);

}  // namespace handskin
