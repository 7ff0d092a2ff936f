#include "rigging/crease.hpp"

#include <algorithm>
#include <cmath>

#include "core/dof.hpp"
#include "core/errors.hpp"
#include "rigging/deform.hpp"

namespace handskin {

CreaseGuard crease_guard(const std::vector<Eigen::Vector3d>& rest, const SkinBinding& binding, const Rig& rig,
                         double keep_fraction) {
  HS_CHECK(rest.size() == binding.vertices.size(), "binding and mesh differ in size");
  CreaseGuard g;
  // Link k runs from joint link_joint(k) to joint k + 1. A joint J > 0 ends link J − 1; the
  // links starting at it are its children (one for every finger joint short of the tip).
  std::vector<int> guard_of(kJointCount, -1);
  for (int k = 0; k + 1 < kJointCount; ++k) {
    const int J = link_joint(k);
    if (J == 0) continue;  // the wrist ends no link
    CreaseGuard::Joint j;
    j.parent_link = J - 1;
    j.child_link = k;
    j.at = rig.joints[J];
    j.d_parent = (rig.joints[J] - rig.joints[link_joint(J - 1)]).normalized();
    j.d_child = (rig.joints[k + 1] - rig.joints[J]).normalized();
    if (!j.d_parent.allFinite() || !j.d_child.allFinite()) continue;
    guard_of[J] = static_cast<int>(g.joints.size());
    g.joints.push_back(j);
  }
  const auto link_length = [&](int k) { return (rig.joints[k + 1] - rig.joints[link_joint(k)]).norm(); };
  for (size_t i = 0; i < rest.size(); ++i) {
    const int l = binding.vertices[i].link[0];  // the dominant link (weights are largest first)
    if (l < 0) continue;
    // The joint at the link's end (the vertex on the parent's side) and at its start (the
    // child's side), when the vertex lies within the link's length of it.
    // (The side is the link's, not the vertex's side of the rest plane: taking the latter left
    // fewer crossings at the PIPs, 2 against 3, but some on the bent finger, and 30 in the fist
    // against 21.) A vertex already on the other side at rest keeps what it had.
    for (const auto& [J, side] : {std::pair<int, float>{l + 1, -1.f}, {link_joint(l), 1.f}}) {
      const int gj = guard_of[J];
      if (gj < 0) continue;
      const CreaseGuard::Joint& j = g.joints[gj];
      if ((rest[i] - j.at).norm() > link_length(l)) continue;
      const Eigen::Vector3d n = (j.d_parent + j.d_child).normalized();
      const double s = side * (rest[i] - j.at).dot(n);
      g.constraints.push_back({static_cast<int>(i), gj, side, static_cast<float>(s > 0 ? keep_fraction * s : s)});
    }
  }
  return g;
}

void guard_creases(const CreaseGuard& g, const std::vector<Eigen::Isometry3d>& motions, std::vector<Eigen::Vector3d>* posed) {
  std::vector<Eigen::Vector3d> at(g.joints.size()), normal(g.joints.size());
  for (size_t k = 0; k < g.joints.size(); ++k) {
    const CreaseGuard::Joint& j = g.joints[k];
    const Eigen::Isometry3d& P = motions[j.parent_link];
    at[k] = P * j.at;
    normal[k] = (P.linear() * j.d_parent + motions[j.child_link].linear() * j.d_child).normalized();
  }
  for (const auto& c : g.constraints) {
    Eigen::Vector3d& v = (*posed)[c.vertex];
    const double s = c.side * (v - at[c.joint]).dot(normal[c.joint]);
    if (s < c.keep) v += (c.keep - s) * c.side * normal[c.joint];
  }
}

Untangled untangle_folds(const std::vector<std::array<int, 3>>& faces, const std::vector<int>& dominant,
                         std::vector<Eigen::Vector3d>* posed, int max_rounds) {
  HS_CHECK(dominant.size() == faces.size(), "one dominant link per face");
  std::vector<Eigen::Vector3d>& x = *posed;
  // Every crossing pair, kept from round to round: after a round only the faces near the
  // vertices it moved are tested again (CrossingFaces), a few hundred of the skin's thousands.
  CrossingFaces crossing(x, faces);
  const auto folding = [&](const std::vector<std::array<int, 2>>& all) {
    std::vector<std::array<int, 2>> out;
    for (const auto& p : all)
      if (links_fold(dominant[p[0]], dominant[p[1]])) out.push_back(p);
    return out;
  };
  Untangled u;
  auto pairs = folding(crossing.pairs());
  u.folding_before = pairs.size();
  if (pairs.empty()) return u;
  std::vector<std::vector<int>> next(x.size());
  for (const auto& f : faces)
    for (int k = 0; k < 3; ++k) next[f[k]].push_back(f[(k + 1) % 3]), next[f[(k + 1) % 3]].push_back(f[k]);
  for (auto& n : next) std::sort(n.begin(), n.end()), n.erase(std::unique(n.begin(), n.end()), n.end());
  std::vector<Eigen::Vector3d> moved(x.size());
  for (; u.rounds < max_rounds && !pairs.empty(); ++u.rounds) {
    std::vector<char> in(x.size(), 0);
    std::vector<int> region;
    for (const auto& p : pairs)
      for (int f : p)
        for (int c : faces[f])
          if (!in[c]) in[c] = 1, region.push_back(c);
    for (int ring = 0; ring < 1 + u.rounds; ++ring)
      for (size_t i = 0, n = region.size(); i < n; ++i)
        for (int c : next[region[i]])
          if (!in[c]) in[c] = 1, region.push_back(c);
    for (int step = 0; step < 10; ++step) {  // Jacobi: every vertex from the previous step's
      for (int i : region) {
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (int c : next[i]) mean += x[c];
        moved[i] = x[i] + 0.5 * (mean / static_cast<double>(next[i].size()) - x[i]);
      }
      for (int i : region) x[i] = moved[i];
    }
    u.moved = region.size();
    pairs = folding(crossing.move(x, region));
  }
  u.folding_after = pairs.size();
  return u;
}

}  // namespace handskin
