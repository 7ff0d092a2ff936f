#include <map>

#include "rigging/deform.hpp"

namespace handskin {

std::vector<int> dominant_links(const std::vector<std::array<int, 3>>& faces, const SkinBinding& binding) {
  std::vector<int> dominant;
  dominant.reserve(faces.size());
  for (const auto& f : faces) {
    std::map<int, double> w;
    for (int c : f)
      for (int k = 0; k < kMaxInfluences && binding.vertices[c].link[k] >= 0; ++k)
        w[binding.vertices[c].link[k]] += binding.vertices[c].weight[k];
    int best = -1;
    double most = -1;
    for (const auto& [l, x] : w)
      if (x > most) most = x, best = l;
    dominant.push_back(best);
  }
  return dominant;
}

bool links_fold(int a, int b) {
  // Link k runs from joint link_joint(k) to joint k + 1; its parent link ends where it starts.
  return a == b || link_joint(a) == b + 1 || link_joint(b) == a + 1;
}

PoseQuality pose_quality(const std::vector<Eigen::Vector3d>& v, const std::vector<std::array<int, 3>>& faces,
                         const SkinBinding* binding) {
  PoseQuality q;
  for (const auto& f : faces) q.volume_mm3 += v[f[0]].dot(v[f[1]].cross(v[f[2]])) / 6;
  const auto pairs = crossing_face_pairs(v, faces);
  q.intersecting_pairs = pairs.size();
  if (binding) {
    const std::vector<int> dominant = dominant_links(faces, *binding);
    for (const auto& [f, g] : pairs)
      if (links_fold(dominant[f], dominant[g])) {
        ++q.folding_pairs;
        q.folding_links.push_back({dominant[f], dominant[g]});
      }
  }
  return q;
}

}  // namespace handskin
