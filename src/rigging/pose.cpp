#include "rigging/pose.hpp"

namespace handskin {

SkinPoser::SkinPoser(const std::vector<Eigen::Vector3d>& rest, const std::vector<std::array<int, 3>>& faces,
                     const SkinBinding& binding, const Rig& rig, bool guard)
    : rest_(rest), faces_(faces), binding_(binding), skeleton_(rig), guard_on_(guard) {
  if (!guard_on_) return;
  guard_ = crease_guard(rest, binding, rig);
  dominant_ = dominant_links(faces, binding);
}

std::vector<Eigen::Vector3d> SkinPoser::pose(const Angles& angles, Blend blend, Untangled* untangled) const {
  const auto motions = link_motions(skeleton_, angles);
  std::vector<Eigen::Vector3d> posed = deform(rest_, binding_, motions, blend);
  if (guard_on_) {
    guard_creases(guard_, motions, &posed);
    const Untangled u = untangle_folds(faces_, dominant_, &posed);
    if (untangled) *untangled = u;
  }
  return posed;
}

}  // namespace handskin
