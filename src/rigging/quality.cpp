#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

#include <iterator>
#include <map>

#include "rigging/deform.hpp"

namespace handskin {

std::vector<std::array<int, 2>> crossing_face_pairs(const std::vector<Eigen::Vector3d>& v,
                                                    const std::vector<std::array<int, 3>>& faces) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Mesh = CGAL::Surface_mesh<K::Point_3>;
  Mesh m;
  std::vector<Mesh::Vertex_index> h;
  h.reserve(v.size());
  for (const auto& p : v) h.push_back(m.add_vertex(K::Point_3(p.x(), p.y(), p.z())));
  for (const auto& f : faces) m.add_face(h[f[0]], h[f[1]], h[f[2]]);
  std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>> pairs;
  CGAL::Polygon_mesh_processing::self_intersections(m, std::back_inserter(pairs));
  std::vector<std::array<int, 2>> out;
  out.reserve(pairs.size());
  for (const auto& [f, g] : pairs) out.push_back({static_cast<int>(f.idx()), static_cast<int>(g.idx())});
  return out;
}

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
