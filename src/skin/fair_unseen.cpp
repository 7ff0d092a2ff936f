#include <CGAL/Polygon_mesh_processing/compute_normal.h>
#include <CGAL/Polygon_mesh_processing/fair.h>

#include <algorithm>
#include <cmath>
#include <deque>

#include "mesh/point_grid.hpp"
#include "skin/skin_steps.hpp"

namespace handskin::skin_steps {

namespace PMP = CGAL::Polygon_mesh_processing;

namespace {
constexpr double kFarMm = 20.0;  // distances to the cloud are looked for this far
constexpr int kHoldRounds = 4;   // fairings at most, each holding the vertices the last took away
}  // namespace

// Step 9. Where neither scan saw the skin, the tubes' union leaves what the rings made of it,
// and two shapes there are not skin: the V between two fingers' tubes over the stretch
// between the palm's end plane (at the most proximal web) and their own web, where the true
// skin is a saddle (the WebXR hand: 1.4 mm off, 14 % of its mean), and the crease where a
// tube's rings meet the palm's across an unseen flank (its thenar: a ridge 3 mm out). Both
// are creases among unseen vertices, and a concave one is where they start: the region is the
// unseen vertices within `rings` edges of an unseen vertex on a concave crease, and it is
// faired with the seen skin round it held (CGAL's `fair`: the cotangent bi-Laplacian, C1 to
// the fixed vertices, Botsch & Kobbelt). Convex creases do not start a region: a finger's
// flank where the section's curvature peaks, tessellated by the decimation, turns 20-40°
// between faces, and fairing it flattens it (tried: 0.003-0.008 mm worse on the family's close,
// wide hand H12). Why not on every unseen vertex: the finger's flanks are bridged by the
// rings' two guesses (step 4), which fit the family's sections better than the least-bending
// surface does (a Hermite bridge was tried there and was worse).
FairUnseen fair_unseen(SM* sm, const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& cut_n, double cut_d,
                       const FairUnseenOptions& o, Moves* moved) {
  FairUnseen f;
  if (!o.enabled) return f;
  const size_t N = sm->num_vertices();  // indexed by vertex index (a decimated mesh keeps removed ones)
  // Seen: a cloud point within seen_mm. The wrist cut's face and its rim are held too: the
  // sawn face is flat and unseen by construction, and its rim a true crease.
  const PointGrid grid(points, std::max(o.seen_mm, 0.5));
  std::vector<char> seen(N, 1);
  for (const auto v : sm->vertices()) {
    const auto& p = sm->point(v);
    const Eigen::Vector3d q(p.x(), p.y(), p.z());
    seen[v.idx()] = cut_n.dot(q) - cut_d < o.cut_margin_mm || grid.any_within(q, o.seen_mm);
    ++f.vertices;
    f.unseen += !seen[v.idx()];
  }
  // Each vertex's tube and ring, where the build kept them (skin_mesh.cpp's "v:origin").
  const auto [origin, has_origin] = sm->property_map<SM::Vertex_index, std::pair<int, int>>("v:origin");
  auto fnormal = sm->add_property_map<SM::Face_index, K::Vector_3>("f:fair_normal", CGAL::NULL_VECTOR).first;
  PMP::compute_face_normals(*sm, fnormal);
  const double cos_crease = std::cos(o.crease_deg * kDeg);
  std::vector<int> depth(N, -1);
  std::deque<SM::Vertex_index> queue;
  for (const auto e : sm->edges()) {
    const auto h = sm->halfedge(e);
    const auto f0 = sm->face(h), f1 = sm->face(sm->opposite(h));
    if (f0 == SM::null_face() || f1 == SM::null_face()) continue;
    if (fnormal[f0] * fnormal[f1] >= cos_crease) continue;
    // Concave: the far corner of the other face lies on the outer side of this one.
    const auto w = sm->target(sm->next(sm->opposite(h)));
    if (fnormal[f0] * (sm->point(w) - sm->point(sm->source(h))) <= 0) continue;
    // A crease between two section rings of one finger is its bent joint's fold on the palmar
    // side, not a seam between tubes: the rings there follow the finger's own section
    // (rings.cpp), and fairing from it flattened a curled finger's unseen palmar side (its
    // PIPs bent 55-60 deg: 944 vertices faired, up to 8.5 mm inward). A crease with a dome
    // ring's vertex (ring -1: a curled fingertip's) still starts a region: left out too, the
    // family's H05 with the automatic skeleton lost 0.016 mm of mean; and so does a fold of
    // the thumb's (tube 1), whose fairing the WebXR hand's bent thumb keeps (0.003 mm).
    if (has_origin) {
      const auto a = origin[sm->source(h)], b = origin[sm->target(h)];
      if (a.first >= 2 && a.first == b.first && a.second >= 0 && b.second >= 0) continue;
    }
    for (const auto v : {sm->source(h), sm->target(h)})
      if (!seen[v.idx()] && depth[v.idx()] < 0) {
        depth[v.idx()] = 0;
        queue.push_back(v);
        ++f.crease_vertices;
      }
  }
  sm->remove_property_map(fnormal);
  while (!queue.empty()) {  // breadth first over unseen vertices, up to `rings` edges
    const auto v = queue.front();
    queue.pop_front();
    if (depth[v.idx()] >= o.rings) continue;
    for (const auto w : CGAL::vertices_around_target(sm->halfedge(v), *sm))
      if (!seen[w.idx()] && depth[w.idx()] < 0) {
        depth[w.idx()] = depth[v.idx()] + 1;
        queue.push_back(w);
      }
  }
  std::vector<SM::Vertex_index> region;
  for (const auto v : sm->vertices())
    if (depth[v.idx()] >= 0) region.push_back(v);
  std::vector<K::Point_3> was;
  for (const auto v : region) was.push_back(sm->point(v));
  const auto to_cloud = [&](const K::Point_3& p) {
    const Eigen::Vector3d q(p.x(), p.y(), p.z());
    const int k = grid.nearest(q, kFarMm);
    return k < 0 ? kFarMm : (points[static_cast<size_t>(k)] - q).norm();
  };
  std::vector<double> was_from_cloud;
  for (const auto& p : was) was_from_cloud.push_back(to_cloud(p));
  // Fair; a vertex the fair surface takes farther from the cloud than it was, by more than
  // away_mm, is held where it was, and the rest faired again with it: the saddle between two
  // fingers lies between their seen sides, no farther from the cloud than the V's floor, while
  // a least-bending surface that bulges away from everything seen is not skin (the WebXR
  // hand's left seed 3, at the thumb's base: a vertex 9 mm out, 1.6 -> 2.6 mm from the true
  // skin; with the few such vertices held, 6 mm and 1.8). Holding at 0.5 mm held the V's
  // floor too: the WebXR hand's mean went 0.077-0.083 -> 0.084-0.088 mm.
  std::vector<char> held(region.size(), 0);
  for (int round = 0; round < kHoldRounds; ++round) {
    std::vector<SM::Vertex_index> free;
    for (size_t k = 0; k < region.size(); ++k) {
      sm->point(region[k]) = was[k];
      if (!held[k]) free.push_back(region[k]);
    }
    if (free.empty() || !PMP::fair(*sm, free)) {  // CGAL moves nothing when its system fails
      for (size_t k = 0; k < region.size(); ++k) sm->point(region[k]) = was[k];
      return f;
    }
    size_t newly = 0;
    for (size_t k = 0; k < region.size(); ++k)
      if (!held[k] && to_cloud(sm->point(region[k])) > was_from_cloud[k] + o.away_mm) held[k] = 1, ++newly;
    if (newly == 0) break;
    if (round + 1 == kHoldRounds)  // still straying: those go back too
      for (size_t k = 0; k < region.size(); ++k)
        if (held[k]) sm->point(region[k]) = was[k];
  }
  for (size_t k = 0; k < region.size(); ++k) {
    const K::Point_3& p = sm->point(region[k]);
    if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || !std::isfinite(p.z())) {
      // never a NaN into the skin: put the region back
      for (size_t j = 0; j < region.size(); ++j) sm->point(region[j]) = was[j];
      return f;
    }
  }
  Moves kept;
  for (size_t k = 0; k < region.size(); ++k)
    if (!held[k]) kept.emplace_back(region[k], was[k]);
  f.held = region.size() - kept.size();
  f.faired = kept.size();
  settle_fair_figures(*sm, kept, nullptr, &f);
  if (moved) moved->insert(moved->end(), kept.begin(), kept.end());
  return f;
}

void settle_fair_figures(const SM& sm, const Moves& moved, const std::vector<K::Point_3>* before, FairUnseen* f) {
  f->taken_back = 0;
  f->mean_move_mm = f->max_move_mm = 0;
  size_t kept = 0;
  for (const auto& [v, was] : moved) {
    if (before && sm.point(v) == (*before)[v.idx()] && sm.point(v) != was) {
      ++f->taken_back;
      continue;
    }
    const double m = std::sqrt(CGAL::squared_distance(sm.point(v), was));
    f->mean_move_mm += m;
    f->max_move_mm = std::max(f->max_move_mm, m);
    ++kept;
  }
  if (kept) f->mean_move_mm /= static_cast<double>(kept);
}

}  // namespace handskin::skin_steps
