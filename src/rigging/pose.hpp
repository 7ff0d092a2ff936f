#pragma once
/// Posing a bound skin (docs/rigging.md): one place for what `pose` and the run's report
/// pictures do with a posture — the links' motions, the skin deformed by its binding, and
/// (with the guard) the crease guard and the folds untangled.
#include <Eigen/Geometry>
#include <array>
#include <string>
#include <vector>

#include "posture/skeleton.hpp"
#include "rigging/binding.hpp"
#include "rigging/crease.hpp"
#include "rigging/deform.hpp"

namespace handskin {

class SkinPoser {
 public:
  /// A skin (`rest` vertices, `faces`) bound by `binding` to `rig`. With `guard`, every
  /// posture gets the crease guard and its folds untangled; what they share (the guard's
  /// planes, the faces' dominant links) is made once here, and only then.
  SkinPoser(const std::vector<Eigen::Vector3d>& rest, const std::vector<std::array<int, 3>>& faces,
            const SkinBinding& binding, const Rig& rig, bool guard);

  /// The skin at `angles`, blended by `blend`; `untangled` (when given) reports what the
  /// guard's untangling did.
  std::vector<Eigen::Vector3d> pose(const Angles& angles, Blend blend, Untangled* untangled = nullptr) const;

 private:
  const std::vector<Eigen::Vector3d>& rest_;
  const std::vector<std::array<int, 3>>& faces_;
  const SkinBinding& binding_;
  Skeleton skeleton_;
  bool guard_on_;
  CreaseGuard guard_;
  std::vector<int> dominant_;
};

}  // namespace handskin
