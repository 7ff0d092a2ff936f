#pragma once
/// The rigged skin as glTF 2.0 binary (`skin.glb`; docs/formats.md, docs/rigging.md), written
/// and read with tinygltf (Debian's libtinygltf-dev):
/// - the skin mesh at the scan posture (POSITION, NORMAL, indices), metres;
/// - a skin over the 25 joints, named as WebXR names them (formats/hand-rig.md), nodes in the
///   skeleton's hierarchy with their rest frames as local transforms, inverse bind matrices
///   the rest frames' inverses, JOINTS_0 / WEIGHTS_0 from the binding (a link's weight goes to
///   its first joint);
/// - a root node "hand" turning the palm frame (Z up from the scanner's table) to glTF's Y up;
/// - in the scene's extras, "handskin": the rig (hand-rig/1, mm), the posture model
///   (hand-posture/1) and the binding mode — everything `pose` needs in one file;
/// - with a texture: TEXCOORD_0 and the image (PNG, in the binary chunk) as the material's
///   base colour. A vertex whose corners lie in different charts is written once per chart:
///   the skin's own vertices come first, in order, and extras.handskin.seam_sources names the
///   skin vertex of each vertex after them, so that reading gives back the skin as it was.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "core/rig.hpp"
#include "core/texture_map.hpp"
#include "mesh/mesh.hpp"
#include "posture/model.hpp"
#include "posture/skeleton.hpp"
#include "rigging/animation.hpp"
#include "rigging/binding.hpp"

namespace handskin {

struct RiggedSkin {
  Mesh mesh;  ///< scan posture, palm frame, mm
  Rig rig;
  SkinBinding binding;
  PostureModel model;
  TextureMap texture;  ///< empty: none (the material is a flat skin tone)
  /// `texture` as PNG when it is encoded already (run encodes it once for texture.png and the
  /// glb); empty: skin_glb encodes it. Must be `texture`'s pixels.
  std::string texture_png;
};

/// A joint node's local transform in skin.glb at a posture: relative to its parent joint (the
/// wrist: to the "hand" node), metres, unit quaternion (x, y, z, w) with w ≥ 0. What viewers
/// (and the studio page) set on the joints to pose the skin.
struct JointNode {
  std::array<double, 3> translation{};
  std::array<double, 4> rotation{0, 0, 0, 1};
};
std::array<JointNode, kJointCount> joint_nodes(const Skeleton& skeleton, const Angles& angles);

/// The glb's bytes; `pose` (if given) sets the joint nodes to that posture (the mesh and the
/// bind matrices stay the scan posture's), so viewers show it posed. `animation` (if given)
/// is written as a glTF animation "handskin": per joint whose rotation changes, a LINEAR
/// rotation sampler over the frames' times (quaternions kept on one hemisphere from frame to
/// frame, so that per-component curves — Blender's — do not flip), and the wrist's
/// translation.
std::vector<unsigned char> skin_glb(const RiggedSkin& skin, const Angles* pose = nullptr,
                                    const PostureAnimation* animation = nullptr);
/// Throws InputError naming `file`: not a glb, no handskin extras or of another version, not
/// the 25 expected joints, non-finite or inconsistent bind matrices, weights that are not
/// weights, a texture that is not a square 8-bit RGB(A) PNG or texture coordinates out of
/// [0, 1], seam vertices that are not copies of their skin vertex.
RiggedSkin read_skin_glb(const std::string& file);

}  // namespace handskin
