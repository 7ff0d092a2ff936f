#pragma once
/// Deforming a bound skin with the skeleton's forward kinematics (docs/rigging.md): each link
/// moves by T_k = W_p(θ)·W_p(0)⁻¹, p its first joint; a vertex by its links' weights, blended
/// linearly (LBS) or as dual quaternions (DQS, Kavan et al. 2008: no candy-wrapper collapse
/// where a joint twists or bends far).
#include <Eigen/Geometry>
#include <array>
#include <string>
#include <vector>

#include "mesh/mesh_check.hpp"  // crossing_face_pairs
#include "posture/skeleton.hpp"
#include "rigging/binding.hpp"

namespace handskin {

/// Per link of bones_from_rig (24): its motion from the rest (scan) posture to `angles`.
std::vector<Eigen::Isometry3d> link_motions(const Skeleton& skeleton, const Angles& angles);

enum class Blend { Linear, DualQuaternion };
/// "lbs" or "dqs"; InputError otherwise.
Blend parse_blend(const std::string& name, const std::string& where);

/// The rest vertices moved. `rest` and `binding` have one entry per vertex.
std::vector<Eigen::Vector3d> deform(const std::vector<Eigen::Vector3d>& rest, const SkinBinding& binding,
                                    const std::vector<Eigen::Isometry3d>& motions, Blend blend);
/// The same into `out` (resized), without allocating per call once sized: for batch posing.
void deform_into(const std::vector<Eigen::Vector3d>& rest, const SkinBinding& binding,
                 const std::vector<Eigen::Isometry3d>& motions, Blend blend, std::vector<Eigen::Vector3d>* out);

}  // namespace handskin

namespace handskin {

/// How a posed skin holds up: pairs of triangles that cross (CGAL's self-intersection test;
/// neighbours sharing a vertex or an edge do not count) and the enclosed volume.
struct PoseQuality {
  size_t intersecting_pairs = 0;
  /// Of those, the pairs that fold at a joint: both faces' dominant links are one link or a
  /// link and its parent (contacts between fingers, or a fingertip on the palm, are not).
  size_t folding_pairs = 0;
  std::vector<std::array<int, 2>> folding_links;  ///< each folding pair's two dominant links
  double volume_mm3 = 0;
};
/// `binding` (optional) gives each face's dominant link (the most weight over its corners).
PoseQuality pose_quality(const std::vector<Eigen::Vector3d>& vertices, const std::vector<std::array<int, 3>>& faces,
                         const SkinBinding* binding = nullptr);

/// Each face's dominant link: the most weight summed over its three corners.
std::vector<int> dominant_links(const std::vector<std::array<int, 3>>& faces, const SkinBinding& binding);
/// Whether two faces with these dominant links fold (one link, or a link and its parent)
/// rather than touch (different fingers, a fingertip on the palm).
bool links_fold(int link_a, int link_b);

}  // namespace handskin
