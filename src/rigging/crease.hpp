#pragma once
/// The crease guard (docs/rigging.md "Creases"): a bent joint's flexion side must not fold
/// into itself. Blended skinning (LBS, DQS) moves the skin on the inside of a bend toward the
/// joint from both links, and past it: the triangles of the two phalanges cross. Here each
/// joint between a link and its child gets the plane through the joint that bisects the two
/// links (posed); a vertex that moves with one of the two links and lies within that link's
/// length of the joint is held on its own link's side of the plane, at least `keep_fraction`
/// of its rest distance from it. The skin on the inside of the bend then gathers in layers
/// against the plane, in the order it had at rest, as a finger's skin does in its flexion
/// crease, instead of passing through the other side's. (A fixed gap instead of a fraction
/// laid the crease's vertices on two sheets, where its triangles crossed each other; on the
/// fixture 0.25 left the fewest crossings of 0.25, 0.5 and 0.8: docs/rigging.md.)
///
/// A rest posture moves nothing (every vertex is where the rest posture had it, so every
/// constraint holds); the guard runs after the blend, in the palm frame, in one pass over
/// the constrained vertices (≈ 40 % of the skin), so it costs about as much as LBS itself.
#include <Eigen/Geometry>
#include <vector>

#include "core/rig.hpp"
#include "rigging/binding.hpp"

namespace handskin {

struct CreaseGuard {
  struct Joint {
    int parent_link = -1, child_link = -1;  ///< the links that end and start at the joint
    Eigen::Vector3d at, d_parent, d_child;  ///< rest position and the links' unit directions
  };
  struct Constraint {
    int vertex = -1, joint = -1;  ///< index into `joints`
    float side = 0;               ///< −1: the parent link's side, +1: the child's
    float keep = 0;               ///< side · (signed distance to the plane) is kept ≥ this, mm
  };
  std::vector<Joint> joints;
  std::vector<Constraint> constraints;
};

/// The guard for a bound skin at rest (`rest`: the vertices the binding was made on).
CreaseGuard crease_guard(const std::vector<Eigen::Vector3d>& rest, const SkinBinding& binding, const Rig& rig,
                         double keep_fraction = 0.25);

/// Hold the posed vertices (after deform) to their sides of each bent joint's plane.
/// `motions`: link_motions of the posture.
void guard_creases(const CreaseGuard& guard, const std::vector<Eigen::Isometry3d>& motions,
                   std::vector<Eigen::Vector3d>* posed);

/// What untangle_folds did.
struct Untangled {
  size_t folding_before = 0, folding_after = 0;  ///< folding face pairs (pose_quality's)
  int rounds = 0;                                ///< smoothing rounds run
  size_t moved = 0;                              ///< vertices smoothed (in the last round's region)
};
/// The second half of the guard. Where the bent skin still crumples onto itself after the
/// planes (pairs of crossing faces whose dominant links fold: one link, or a link and its
/// parent; links_fold), the faces' vertices and `1 + round` rings of their neighbours are
/// smoothed (umbrella steps, x ← x + ½(mean of neighbours − x), 10 per round; the rest of the
/// skin is held), until no folding pair is left or `max_rounds` rounds. Contacts between
/// fingers or with the palm are left as they are. Costs a self-intersection test per round
/// (tens of ms on 8000 triangles): for `pose`'s outputs and the report's pictures, not for
/// batch posing.
Untangled untangle_folds(const std::vector<std::array<int, 3>>& faces, const std::vector<int>& dominant_links,
                         std::vector<Eigen::Vector3d>* posed, int max_rounds = 8);

}  // namespace handskin
