#include "skin/skin_steps.hpp"

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Random.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <CGAL/boost/graph/Euler_operations.h>

#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/corefinement.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/repair_self_intersections.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cmath>
#include <cstdlib>
#include <set>

#include "core/errors.hpp"

namespace handskin::skin_steps {

namespace PMP = CGAL::Polygon_mesh_processing;

namespace {

/// Edges of the union shorter than this (1 µm; a float's step at 300 mm is 0.03 µm) are
/// collapsed (collapse_short_edges).
constexpr double kMicroEdgeMm = 1e-3;
// The most crossing pairs mend_crossings takes on.
constexpr size_t kMendMaxPairs = 100;

// Move each ring point out (or, where the ring is concave, in) by half the sagitta of its
// chords, so that the polygon straddles the curve it samples instead of lying inside it: the
// chords' largest distance from the curve halves (the minimax polygon of a circle).
void straddle(std::vector<Eigen::Vector3d>* ring, const Eigen::Vector3d& centre) {
  const std::vector<Eigen::Vector3d> p = *ring;
  const size_t M = p.size();
  for (size_t j = 0; j < M; ++j) {
    const Eigen::Vector3d &a = p[(j + M - 1) % M], &b = p[j], &c = p[(j + 1) % M];
    const Eigen::Vector3d ab = b - a, bc = c - b, ca = a - c;
    const double area2 = ab.cross(bc).norm();
    if (area2 < 1e-12) continue;
    const double R = ab.norm() * bc.norm() * ca.norm() / (2 * area2);  // circumradius
    const double chord = 0.5 * (ab.norm() + bc.norm());
    Eigen::Vector3d out = (b - 0.5 * (a + c));  // toward the outside of a convex corner
    const bool convex = out.dot(b - centre) > 0;
    const Eigen::Vector3d radial = (b - centre).normalized();
    const double sag = std::min(chord * chord / (8 * R), 0.25 * chord);
    (*ring)[j] = b + (convex ? 0.5 : -0.5) * sag * radial;
  }
}

// A planar ring (`ids` into V, in the tube's order) triangulated on its own vertices, inside
// the polygon only: the constrained Delaunay triangulation of its outline in its plane (CGAL),
// the triangles whose centroid lies inside kept, each wound as `outward` asks (the ring's own
// order when true). Empty when the outline is not a simple polygon (two vertices in one place,
// or edges that cross: the triangulation then has other vertices or other than n − 2 triangles).
std::vector<std::array<int, 3>> flat_cap(const std::vector<Eigen::Vector3d>& V, const std::vector<int>& ids, bool outward) {
  using K2 = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Vb = CGAL::Triangulation_vertex_base_with_info_2<int, K2>;
  using Tds = CGAL::Triangulation_data_structure_2<Vb, CGAL::Constrained_triangulation_face_base_2<K2>>;
  using CDT = CGAL::Constrained_Delaunay_triangulation_2<K2, Tds, CGAL::No_constraint_intersection_tag>;
  const int n = static_cast<int>(ids.size());
  Eigen::Vector3d c = Eigen::Vector3d::Zero(), normal = Eigen::Vector3d::Zero();
  for (int id : ids) c += V[id];
  c /= n;
  for (int j = 0; j < n; ++j) normal += (V[ids[j]] - c).cross(V[ids[(j + 1) % n]] - c);  // Newell: along the ring's own winding
  if (normal.norm() < 1e-12) return {};
  normal.normalize();
  const Eigen::Vector3d e1 = normal.unitOrthogonal(), e2 = normal.cross(e1);
  std::vector<K2::Point_2> q(n);
  for (int j = 0; j < n; ++j) q[j] = K2::Point_2((V[ids[j]] - c).dot(e1), (V[ids[j]] - c).dot(e2));
  std::vector<std::array<int, 3>> tris;
  try {
    CDT cdt;
    std::vector<CDT::Vertex_handle> vh(n);
    for (int j = 0; j < n; ++j) vh[j] = cdt.insert(q[j]), vh[j]->info() = j;
    if (static_cast<int>(cdt.number_of_vertices()) != n) return {};
    for (int j = 0; j < n; ++j) cdt.insert_constraint(vh[j], vh[(j + 1) % n]);
    if (static_cast<int>(cdt.number_of_vertices()) != n) return {};
    for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
      const K2::Point_2 m = CGAL::centroid(f->vertex(0)->point(), f->vertex(1)->point(), f->vertex(2)->point());
      if (CGAL::bounded_side_2(q.begin(), q.end(), m, K2()) != CGAL::ON_BOUNDED_SIDE) continue;
      std::array<int, 3> t{f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()};
      // In the (e1, e2) frame the ring winds counter-clockwise (the normal is its Newell
      // normal); the triangulation's faces are counter-clockwise too.
      if (!outward) std::swap(t[1], t[2]);
      tris.push_back({ids[t[0]], ids[t[1]], ids[t[2]]});
    }
  } catch (const std::exception&) {  // constraints that intersect (No_constraint_intersection_tag)
    return {};
  }
  if (static_cast<int>(tris.size()) != n - 2) return {};
  return tris;
}

// The tube's triangles (outward): strips between consecutive rings (each quad split along
// its shorter diagonal), a flat fan over the first ring, a pole fan or a flat fan at the end.
// With `flat_caps` an end without a pole is instead triangulated on the ring's own vertices
// (flat_cap), where that ring is a simple polygon: a fan from the centroid of a ring that is
// not star-shaped from it (a palm section cut where a low thumb or a bent finger leaves a deep
// notch in its outline) folds over itself.
void tube_mesh(const TubeBuild& t, std::vector<Eigen::Vector3d>* V, std::vector<std::array<int, 3>>* F,
               std::vector<int>* ring_of, bool flat_caps = false) {
  const int M = static_cast<int>(t.rings.front().size());
  V->clear(), F->clear(), ring_of->clear();
  for (size_t k = 0; k < t.rings.size(); ++k) {
    std::vector<Eigen::Vector3d> ring = t.rings[k];
    straddle(&ring, t.ring_centre[k]);
    for (const auto& p : ring) V->push_back(p), ring_of->push_back(t.ring_station[k]);
  }
  auto id = [&](size_t k, int j) { return static_cast<int>(k) * M + ((j % M) + M) % M; };
  for (size_t k = 0; k + 1 < t.rings.size(); ++k)
    for (int j = 0; j < M; ++j) {
      const int a = id(k, j), b = id(k, j + 1), c = id(k + 1, j + 1), d = id(k + 1, j);
      if (((*V)[a] - (*V)[c]).squaredNorm() <= ((*V)[b] - (*V)[d]).squaredNorm())
        F->push_back({a, b, c}), F->push_back({a, c, d});
      else
        F->push_back({a, b, d}), F->push_back({b, c, d});
    }
  auto centroid = [&](size_t k) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const auto& p : t.rings[k]) c += p;
    return Eigen::Vector3d(c / M);
  };
  const size_t L = t.rings.size() - 1;
  const auto ring_ids = [&](size_t k) {
    std::vector<int> ids(M);
    for (int j = 0; j < M; ++j) ids[j] = id(k, j);
    return ids;
  };
  // The first ring's cap faces back along the tube (against the ring's winding), the end's on.
  std::vector<std::array<int, 3>> first = flat_caps ? flat_cap(*V, ring_ids(0), false) : std::vector<std::array<int, 3>>();
  std::vector<std::array<int, 3>> last = flat_caps && !t.pole ? flat_cap(*V, ring_ids(L), true) : std::vector<std::array<int, 3>>();
  if (first.empty()) {
    const int root = static_cast<int>(V->size());
    V->push_back(centroid(0)), ring_of->push_back(-1);
    for (int j = 0; j < M; ++j) F->push_back({root, id(0, j + 1), id(0, j)});
  }
  F->insert(F->end(), first.begin(), first.end());
  if (last.empty()) {
    const int end = static_cast<int>(V->size());
    V->push_back(t.pole ? *t.pole : centroid(L)), ring_of->push_back(-1);
    for (int j = 0; j < M; ++j) F->push_back({end, id(L, j), id(L, j + 1)});
  }
  F->insert(F->end(), last.begin(), last.end());
}

SM to_surface_mesh(const std::vector<Eigen::Vector3d>& V, const std::vector<std::array<int, 3>>& F) {
  SM sm;
  std::vector<SM::Vertex_index> vi;
  for (const auto& p : V) vi.push_back(sm.add_vertex(K::Point_3(p.x(), p.y(), p.z())));
  for (const auto& f : F) HS_CHECK(sm.add_face(vi[f[0]], vi[f[1]], vi[f[2]]) != SM::null_face(), "face rejected");
  return sm;
}

// The corefinement's output order follows its containers' memory addresses, which change with
// what other threads allocate: the same union came out in another vertex order now and then
// (and decimation, which breaks ties by order, then differed too). Vertices sorted by
// position, each face starting at its smallest index, faces sorted: one order for one surface.
SM canonical_order(const SM& in) {
  std::vector<SM::Vertex_index> order(in.vertices().begin(), in.vertices().end());
  auto key = [&](SM::Vertex_index v) {
    const auto& p = in.point(v);
    return std::array<double, 3>{p.x(), p.y(), p.z()};
  };
  std::sort(order.begin(), order.end(), [&](SM::Vertex_index a, SM::Vertex_index b) { return key(a) < key(b); });
  std::vector<std::uint32_t> rank(in.number_of_vertices() + in.number_of_removed_vertices());
  for (std::size_t k = 0; k < order.size(); ++k) rank[order[k].idx()] = static_cast<std::uint32_t>(k);
  std::vector<std::array<std::uint32_t, 3>> faces;
  for (auto f : in.faces()) {
    std::array<std::uint32_t, 3> t{};
    int k = 0;
    for (auto v : CGAL::vertices_around_face(in.halfedge(f), in)) t[k++] = rank[v.idx()];
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());  // keeps the orientation
    faces.push_back(t);
  }
  std::sort(faces.begin(), faces.end());
  SM out;
  std::vector<SM::Vertex_index> vh;
  for (auto v : order) vh.push_back(out.add_vertex(in.point(v)));
  for (const auto& t : faces) out.add_face(vh[t[0]], vh[t[1]], vh[t[2]]);
  return out;
}

// The corefinement cuts each surface where the other crosses it. Where the palm and a digit's
// base cross almost along one line (a little finger's root placed at the palm's edge), it
// leaves clusters of vertices micrometres apart, joined by slivers. Once rounded to the floats
// skin.ply stores they coincide, their triangles are degenerate and the skin "crosses itself"
// (H04 of the family as two halves; docs/skin.md). Every edge shorter than `eps` is collapsed
// where the link condition allows it; the vertex kept keeps its position, so that its origin
// (tube, ring) is still found by position. CGAL's experimental remove_almost_degenerate_faces
// also flips caps, which would change the skin elsewhere; only the micro-edges are wanted.
void collapse_short_edges(SM* sm, double eps) {
  const auto is_short = [&](SM::Edge_index e) {
    const auto h = sm->halfedge(e);
    return CGAL::squared_distance(sm->point(sm->source(h)), sm->point(sm->target(h))) < eps * eps;
  };
  for (bool again = true; again;) {
    again = false;
    std::vector<SM::Edge_index> candidates;
    for (auto e : sm->edges())
      if (is_short(e)) candidates.push_back(e);
    for (auto e : candidates) {  // a collapse before may have removed or lengthened it
      if (sm->is_removed(e) || !is_short(e) || !CGAL::Euler::does_satisfy_link_condition(e, *sm)) continue;
      CGAL::Euler::collapse_edge(e, *sm);
      again = true;
    }
  }
  sm->collect_garbage();
}

}  // namespace

int mend_crossings(SM* sm) {
  std::vector<std::pair<SM::Face_index, SM::Face_index>> pairs;
  PMP::self_intersections(*sm, std::back_inserter(pairs));
  if (pairs.empty()) return 0;
  // The repair took 0.9 s for R07's 13 pairs at one spot; a skin crossing itself in many places
  // is not a union's sliver but a fold, and is refused as it was, without the wait.
  if (pairs.size() > kMendMaxPairs) return -1;
  std::set<SM::Face_index> crossing;
  for (const auto& [a, b] : pairs) crossing.insert(a), crossing.insert(b);
  // CGAL's repair (experimental in 5.5): the crossing faces and a neighbourhood around them
  // removed and the hole filled, or smoothed, until nothing there crosses.
  CGAL::get_default_random() = CGAL::Random(1);
  const bool done =
      PMP::experimental::remove_self_intersections(crossing, *sm, CGAL::parameters::preserve_genus(true));
  sm->collect_garbage();
  round_as_written(sm);
  if (!done || !CGAL::is_closed(*sm) || PMP::does_self_intersect(*sm)) return -1;
  return static_cast<int>(pairs.size());
}

SM stitch_tubes(const std::vector<TubeBuild>& tubes, const Eigen::Isometry3d& Ti,
                PositionOrigin* origin_out, int* pockets_out, bool mend_caps, bool fault_palm_folds) {
  auto& origin = *origin_out;
  *pockets_out = 0;
  // CGAL's box intersection (inside the self-intersection checks and the corefinement) draws
  // from the default random, which is seeded from the clock: the union's vertex order then
  // changed from run to run. Seeded here, in the thread that builds the skin.
  CGAL::get_default_random() = CGAL::Random(1);
  // The digits, which do not touch one another (keep_apart), go in as
  // one mesh of five shells, so that the palm is stitched to all of them in a single
  // corefinement. Corefinement needs inputs free of self-intersections: the palm is checked,
  // and the five digits at once, which covers each digit's own folds as well as digits
  // touching. Only if that check fails is each digit checked on its own, to name the one that
  // folds; if none does, two digits touch (e.g. the thumb lying on the index) and they are
  // stitched one by one instead.
  std::vector<SM> parts;
  std::vector<const TubeBuild*> part_build;
  std::vector<int> part_tube;
  const auto make_part = [&](const TubeBuild& t, bool flat_caps) {
    std::vector<Eigen::Vector3d> V;
    std::vector<std::array<int, 3>> F;
    std::vector<int> ring_of;
    tube_mesh(t, &V, &F, &ring_of, flat_caps);
    for (auto& p : V) p = Ti * p;
    for (size_t i = 0; i < V.size(); ++i) origin[{V[i].x(), V[i].y(), V[i].z()}] = {t.id, ring_of[i]};
    return to_surface_mesh(V, F);
  };
  for (const auto& t : tubes) {
    if (!t.report.present) continue;
    parts.push_back(make_part(t, false));
    part_build.push_back(&t);
    part_tube.push_back(t.id);
  }
  // A part that folds is made again with its open ends triangulated on their rings (tube_mesh's
  // flat_caps): a fan over a notched ring is the one fold this can mend. True when it no longer folds.
  const auto unfold_caps = [&](size_t k) {
    if (!mend_caps) return false;
    SM again = make_part(*part_build[k], true);
    if (again.number_of_faces() == parts[k].number_of_faces() || PMP::does_self_intersect(again)) return false;
    parts[k] = std::move(again);
    return true;
  };
  auto folds = [&](size_t k) {
    return TubeFoldsError("merged cloud",
                          std::string("the ") + skin_tube_name(part_tube[k]) +
                              " tube folds into itself; the rig may be badly placed for this scan",
                          part_tube[k]);
  };
  auto unite = [&](SM& a, SM& b, const std::string& what) {
    SM out;
    if (!PMP::corefine_and_compute_union(a, b, out))
      throw InputError("merged cloud", "the " + what + " cannot be stitched to the palm into a closed manifold");
    return out;
  };
  SM digits;
  for (size_t k = 1; k < parts.size(); ++k) {
    std::vector<SM::Vertex_index> map(parts[k].number_of_vertices());
    for (auto v : parts[k].vertices()) map[v.idx()] = digits.add_vertex(parts[k].point(v));
    for (auto f : parts[k].faces()) {
      std::vector<SM::Vertex_index> tri;
      for (auto v : CGAL::vertices_around_face(parts[k].halfedge(f), parts[k])) tri.push_back(map[v.idx()]);
      digits.add_face(tri[0], tri[1], tri[2]);
    }
  }
  // The palm's test and the digits' run side by side (one thread each; CGAL's own parallel
  // test, over TBB, was slower here than its sequential one).
  bool palm_folds = false, digits_cross = false;
#pragma omp parallel sections
  {
#pragma omp section
    palm_folds = PMP::does_self_intersect(parts[0]);
#pragma omp section
    digits_cross = parts.size() > 1 && PMP::does_self_intersect(digits);
  }
  if (palm_folds && !fault_palm_folds) palm_folds = !unfold_caps(0);
  if (fault_palm_folds) palm_folds = true;  // fault injection (build_skin)
  if (palm_folds) throw folds(0);
  CGAL::get_default_random() = CGAL::Random(1);  // the tests drew from it (the union's order, below)
  SM skin = std::move(parts.front());  // the palm
  if (parts.size() > 1 && !digits_cross) {
    skin = unite(skin, digits, "digits");
  } else {
    for (size_t k = 1; k < parts.size(); ++k)
      if (PMP::does_self_intersect(parts[k]) && !unfold_caps(k)) throw folds(k);
    for (size_t k = 1; k < parts.size(); ++k) skin = unite(skin, parts[k], skin_tube_name(part_tube[k]) + std::string(" tube"));
  }
  // The union's boundary also bounds any pocket the tubes enclose between them: inward-facing
  // shells inside the skin. They are dropped; a second outward shell would be a digit that
  // does not meet the palm, which is an error. Counting the components first spares the copy
  // into pieces in the usual case of one.
  auto component = skin.add_property_map<SM::Face_index, std::size_t>("f:component", 0).first;
  const std::size_t components = PMP::connected_components(skin, component);
  skin.remove_property_map(component);
  if (components > 1) {
    std::vector<SM> pieces;
    PMP::split_connected_components(skin, pieces);
    SM outer;
    int outward = 0, pockets = 0;
    for (auto& piece : pieces) {
      if (PMP::volume(piece) > 0) {
        ++outward;
        outer = std::move(piece);
      } else {
        ++pockets;
      }
    }
    if (outward != 1)
      throw InputError("merged cloud", "the skin's tubes do not join into one surface (" + std::to_string(outward) +
                                           " separate pieces); the rig may not fit this scan");
    *pockets_out = pockets;
    skin = std::move(outer);
  }
  // The union's new vertices (where one tube's triangles cross another's) snapped to a grid of
  // 2^-20 mm (~1e-6 mm). CGAL's corefinement computes a few of them through constructions whose
  // evaluation follows its containers' order, and so memory addresses: on a random hand (R04 of
  // `scripts/random_hands_study.py --draw 73`) one or two of its 6 400 came out 1 ulp (1e-14 mm)
  // apart from run to run, and the steps after (the micro-edges' collapses, decimation's ties,
  // the fit) carried that into skins 0.0003 mm apart in mean: the same inputs gave other bytes.
  // A grid step 10^8 ulps wide makes a 1-ulp difference cross a grid line about once in 10^8.
  // The tubes' own vertices stay exact: their origin (tube, ring) is found by position.
  for (auto v : skin.vertices()) {
    const auto& p = skin.point(v);
    if (origin.count({p.x(), p.y(), p.z()})) continue;
    const auto snap = [](double x) { return std::ldexp(std::nearbyint(std::ldexp(x, 20)), -20); };
    skin.point(v) = K::Point_3(snap(p.x()), snap(p.y()), snap(p.z()));
  }
  // The micro-edges collapsed in one order for one surface (the union's own order follows
  // memory addresses; which end of an edge stays, and which collapse the link condition
  // refuses, follow the order they are taken in).
  SM ordered = canonical_order(skin);
  collapse_short_edges(&ordered, kMicroEdgeMm);
  return canonical_order(ordered);
}

}  // namespace handskin::skin_steps

