#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

#include <iterator>
#include <map>

#include "rigging/deform.hpp"

namespace handskin {

PoseQuality pose_quality(const std::vector<Eigen::Vector3d>& v, const std::vector<std::array<int, 3>>& faces,
                         const SkinBinding* binding) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Mesh = CGAL::Surface_mesh<K::Point_3>;
  Mesh m;
  std::vector<Mesh::Vertex_index> h;
  for (const auto& p : v) h.push_back(m.add_vertex(K::Point_3(p.x(), p.y(), p.z())));
  PoseQuality q;
  for (const auto& f : faces) {
    m.add_face(h[f[0]], h[f[1]], h[f[2]]);
    q.volume_mm3 += v[f[0]].dot(v[f[1]].cross(v[f[2]])) / 6;
  }
  std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>> pairs;
  CGAL::Polygon_mesh_processing::self_intersections(m, std::back_inserter(pairs));
  q.intersecting_pairs = pairs.size();
  if (binding) {
    std::vector<int> dominant;
    for (const auto& f : faces) {
      std::map<int, double> w;
      for (int c : f)
        for (int k = 0; k < kMaxInfluences && binding->vertices[c].link[k] >= 0; ++k)
          w[binding->vertices[c].link[k]] += binding->vertices[c].weight[k];
      int best = -1;
      double most = -1;
      for (const auto& [l, x] : w)
        if (x > most) most = x, best = l;
      dominant.push_back(best);
    }
    // Link k runs from joint link_joint(k) to joint k + 1; its parent link ends where it starts.
    auto adjacent = [](int a, int b) { return a == b || link_joint(a) == b + 1 || link_joint(b) == a + 1; };
    for (const auto& [f, g] : pairs)
      if (adjacent(dominant[f.idx()], dominant[g.idx()])) {
        ++q.folding_pairs;
        q.folding_links.push_back({dominant[f.idx()], dominant[g.idx()]});
      }
  }
  return q;
}

}  // namespace handskin
