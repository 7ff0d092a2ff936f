// The patches' control points bound smoothly from the polygon skin's binding, and the
// patches posed (patches.hpp: bind_patch_controls, pose_patch_skin).
#include <algorithm>
#include <map>

#include "core/errors.hpp"
#include "mesh/triangle_tree.hpp"
#include "patches/patches.hpp"

namespace handskin {

void bind_patch_controls(PatchSkin* s, const Mesh& skin, const SkinBinding& binding) {
  const std::vector<Eigen::Vector3d>& V = skin.vertices;
  const std::vector<std::array<int, 3>>& F = skin.faces;
  if (binding.vertices.size() != V.size())
    throw InputError("patches", "the skin's binding has " + std::to_string(binding.vertices.size()) +
                                    " vertices, the skin " + std::to_string(V.size()));
  if (F.empty()) throw InputError("patches", "the skin to bind the patches from has no triangles");
  const cgal::TriangleTree tt(V, F);
  s->control_weights.assign(s->control.size(), VertexWeights{});
  for (size_t k = 0; k < s->control.size(); ++k) {
    const auto [q, prim] = tt.tree.closest_point_and_primitive(cgal::point(s->control[k]));
    const auto& t = F[static_cast<size_t>(prim - tt.triangles.begin())];
    // Barycentric coordinates of the nearest point in its triangle (clamped: it lies on it).
    const Eigen::Vector3d a = V[t[0]], b = V[t[1]], c = V[t[2]], p(q.x(), q.y(), q.z());
    const Eigen::Vector3d n = (b - a).cross(c - a);
    double bary[3] = {1.0 / 3, 1.0 / 3, 1.0 / 3};
    if (n.squaredNorm() > 1e-24) {
      bary[0] = std::max(0.0, (c - b).cross(p - b).dot(n) / n.squaredNorm());
      bary[1] = std::max(0.0, (a - c).cross(p - c).dot(n) / n.squaredNorm());
      bary[2] = std::max(0.0, (b - a).cross(p - a).dot(n) / n.squaredNorm());
      const double sum = bary[0] + bary[1] + bary[2];
      for (double& x : bary) x = sum > 0 ? x / sum : 1.0 / 3;
    }
    // The three corners' weights blended; the kMaxInfluences largest kept, normalised.
    std::map<int, double> mix;
    for (int i = 0; i < 3; ++i) {
      const VertexWeights& w = binding.vertices[t[i]];
      for (int j = 0; j < kMaxInfluences; ++j)
        if (w.link[j] >= 0) mix[w.link[j]] += bary[i] * w.weight[j];
    }
    std::vector<std::pair<double, int>> pairs;
    for (const auto& [link, w] : mix) pairs.push_back({w, link});
    s->control_weights[k] = top_weights(std::move(pairs), 0.0);  // the skin's already dropped its small ones
  }
  s->binding_mode = binding.mode;
}

PatchSkin pose_patch_skin(const PatchSkin& s, const Skeleton& skeleton, const Angles& angles, Blend blend) {
  const std::vector<Eigen::Isometry3d> move = link_motions(skeleton, angles);
  HS_CHECK(s.bones.size() == move.size(), "patches bound to another skeleton");
  PatchSkin out = s;
  out.samples.clear();
  out.crossings.reset();  // the rest surface's, as the samples: not this posture's
  if (!s.control_weights.empty()) {
    HS_CHECK(s.control_weights.size() == s.control.size(), "a control point without its weights");
    SkinBinding b;
    b.vertices = s.control_weights;
    out.control = deform(s.control, b, move, blend);
  } else {
    for (size_t k = 0; k < out.control.size(); ++k) {
      const int l = out.control_link[k];
      HS_CHECK(l >= 0 && l < static_cast<int>(move.size()), "a control point without its link");
      out.control[k] = move[l] * out.control[k];
    }
  }
  rebuild_patches(&out);
  return out;
}

}  // namespace handskin
