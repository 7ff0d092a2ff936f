#include "skin/skin_steps.hpp"

#include <CGAL/Surface_mesh_simplification/Edge_collapse_visitor_base.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/GarlandHeckbert_plane_policies.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>

#include <cmath>

namespace handskin::skin_steps {

namespace {


/// Edge-collapse filter: refuses a placement that turns any surviving triangle of the
/// collapse's star by more than the angle whose cosine is `cos_max` (CGAL's
/// Bounded_normal_change_filter only refuses flips, i.e. 90°, which still lets the thin web
/// and fingertip strips crease).
struct NormalDeviationFilter {
  double cos_max;
  template <class Profile>
  boost::optional<typename Profile::Point> operator()(const Profile& profile,
                                                      boost::optional<typename Profile::Point> op) const {
    if (!op) return op;
    const auto& vpm = profile.vertex_point_map();
    const auto& tris = profile.triangles();
    // The first one or two triangles are the ones that vanish with the edge; in the rest, v1
    // is the vertex that moves to the placement.
    size_t first = (profile.left_face_exists() ? 1 : 0) + (profile.right_face_exists() ? 1 : 0);
    for (size_t i = first; i < tris.size(); ++i) {
      const K::Point_3 &p = get(vpm, tris[i].v0), &q = get(vpm, tris[i].v1), &r = get(vpm, tris[i].v2);
      const K::Vector_3 n1 = CGAL::cross_product(p - q, r - q), n2 = CGAL::cross_product(p - *op, r - *op);
      const double d = n1 * n2, l = std::sqrt((n1 * n1) * (n2 * n2));
      if (!(l > 0) || d < cos_max * l) return boost::none;
    }
    return op;
  }
};

/// Stops at the triangle budget (a closed triangle mesh has 3F/2 edges) or when the cheapest
/// collapse would move the surface more than the tolerance (the quadric error is a squared
/// distance).
struct BudgetOrToleranceStop {
  size_t max_edges;
  double max_cost;
  template <class FT, class Profile>
  bool operator()(const FT& cost, const Profile&, std::size_t, std::size_t edges) const {
    return edges <= max_edges || cost > max_cost;
  }
};

/// Keeps each vertex's (tube, ring) through the collapses: the survivor takes the origin of
/// whichever end of the edge its new position lies nearer.
struct OriginVisitor : CGAL::Surface_mesh_simplification::Edge_collapse_visitor_base<SM> {
  Origin* origin;
  template <class Profile>
  void OnCollapsed(const Profile& profile, SM::Vertex_index kept) {
    const auto& p = get(profile.vertex_point_map(), kept);
    const bool first = CGAL::squared_distance(p, profile.p0()) <= CGAL::squared_distance(p, profile.p1());
    (*origin)[kept] = (*origin)[first ? profile.v0() : profile.v1()];
  }
};

}  // namespace

/// Quadric-error decimation of a closed mesh to `max_faces`, moving it by at most about
/// `tolerance_mm`, with garbage collected afterwards (the property maps follow).
void decimate(SM* sm, size_t max_faces, double tolerance_mm, Origin origin) {
  namespace SMS = CGAL::Surface_mesh_simplification;
  SMS::GarlandHeckbert_plane_policies<SM, K> quadrics(*sm);
  OriginVisitor visitor;
  visitor.origin = &origin;
  SMS::edge_collapse(*sm, BudgetOrToleranceStop{max_faces * 3 / 2, tolerance_mm * tolerance_mm},
                     CGAL::parameters::get_cost(quadrics.get_cost())
                         .get_placement(quadrics.get_placement())
                         .filter(NormalDeviationFilter{std::cos(20.0 * kDeg)})
                         .visitor(visitor));
  sm->collect_garbage();
}


}  // namespace handskin::skin_steps
