#pragma once
/// A colour texture on a triangle mesh: one square RGB image and, per face, the texture
/// coordinates of its three corners (glTF's convention: u right, v down from the image's first
/// row, both in [0, 1]). Corners of one vertex may differ where charts meet, so the map is per
/// corner and the mesh's vertices stay as they are.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

namespace handskin {

struct TextureMap {
  int size = 0;                                          ///< the image is size × size
  std::vector<std::uint8_t> rgb;                         ///< row-major, 3 bytes a texel
  std::vector<std::array<Eigen::Vector2f, 3>> corner_uv; ///< per face, its corners' (u, v)
  bool empty() const { return size == 0; }
};

}  // namespace handskin
