#pragma once
/// Binding a skin to the skeleton (thesis §4.1.5; docs/rigging.md): which bone links move each
/// vertex, and how much.
/// - "rigid" (the thesis): every vertex moves with its nearest link.
/// - "smooth" (the default): bone-heat weights (Baran & Popović 2007): for each link i,
///   (L + M·H)·w_i = M·H·p_i over the mesh, with L the cotangent Laplacian, M the lumped vertex
///   areas, H_jj = c / d_j² (d_j the vertex's distance to its nearest link) and p_ij = 1 where
///   link i is that nearest link. At most 4 influences per vertex, normalised to sum 1.
/// Links are those of bones_from_rig (24); link k moves with the frame of its first joint.
#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "core/rig.hpp"
#include "mesh/mesh.hpp"

namespace handskin {

constexpr int kMaxInfluences = 4;

struct VertexWeights {
  std::array<int, kMaxInfluences> link{-1, -1, -1, -1};  ///< index into bones_from_rig, -1 unused
  std::array<float, kMaxInfluences> weight{0, 0, 0, 0};  ///< sum 1, largest first
};

struct BindingOptions {
  std::string mode = "smooth";  ///< "smooth" or "rigid"
  double heat = 1.0;            ///< c of H_jj = c / d_j²
  /// Weights below this (after keeping the 4 largest) are dropped before normalising.
  double min_weight = 1e-3;
  bool IsValid(std::string* error) const;
};

struct SkinBinding {
  std::string mode;
  std::vector<VertexWeights> vertices;  ///< per mesh vertex
  double seconds = 0;
};

/// Of (weight, link) pairs, the kMaxInfluences largest (ties: the lower link first), those
/// after the first only when at least min_weight, normalised, largest first. Where they sum to
/// nothing, the first pair's link alone.
VertexWeights top_weights(std::vector<std::pair<double, int>> w, double min_weight);

/// Throws InputError if the mesh has no vertices or the rig gives no links.
SkinBinding bind_skin(const Mesh& mesh, const std::vector<Bone>& bones, const BindingOptions& options);

/// The joint each link moves with (its first joint): joints()[k + 1].parent for link k.
int link_joint(int link);

}  // namespace handskin
