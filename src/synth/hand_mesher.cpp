#include "synth/hand_mesher.hpp"

#include <CGAL/Complex_2_in_triangulation_3.h>
#include <CGAL/IO/facets_in_complex_2_to_triangle_mesh.h>
#include <CGAL/Implicit_surface_3.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Random.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_default_triangulation_3.h>
#include <CGAL/make_surface_mesh.h>

#include <chrono>

#include "core/errors.hpp"
#include "mesh/from_cgal.hpp"

namespace handskin {

namespace {
using Tr = CGAL::Surface_mesh_default_triangulation_3;
using C2t3 = CGAL::Complex_2_in_triangulation_3<Tr>;
using GT = Tr::Geom_traits;
using Point_3 = GT::Point_3;
using FT = GT::FT;

struct HandFunction {
  const HandModel* model;
  FT operator()(const Point_3& p) const { return model->value(Eigen::Vector3d(p.x(), p.y(), p.z())); }
};
}  // namespace

bool HandMeshOptions::IsValid(std::string* error) const {
  if (!(facet_angle_deg > 0 && facet_angle_deg <= 30)) return invalid(error, "facet_angle_deg must be in (0, 30]");
  if (!(facet_size_mm >= 0.3 && facet_size_mm <= 10)) return invalid(error, "facet_size_mm must be in [0.3, 10]");
  if (!(facet_distance_mm >= 0.005 && facet_distance_mm <= 1)) return invalid(error, "facet_distance_mm must be in [0.005, 1]");
  return true;
}

HandMeshResult mesh_hand(const HandModel& model, const HandMeshOptions& options) {
  std::string err;
  if (!options.IsValid(&err)) throw InputError("mesh options", err);
  const auto t0 = std::chrono::steady_clock::now();
  // make_surface_mesh draws its initial points from CGAL's default random, which is seeded
  // from the clock: reseed it. (Its refinement queue is ordered by cell addresses, so the mesh
  // is reproducible per fresh process, as the CLI runs it, not between calls in one process.)
  CGAL::get_default_random() = CGAL::Random(options.seed);

  // Bounding sphere centred inside the palm (the oracle needs a negative value there).
  const Eigen::Vector3d centre = model.rig.joints[joint_index("middle-finger-metacarpal").value()] * 0.5 +
                                 model.rig.joints[joint_index("middle-finger-phalanx-proximal").value()] * 0.5;
  HS_CHECK(model.value(centre) < 0, "bounding-sphere centre is not inside the hand");
  const double radius = (model.box_max - model.box_min).norm() * 0.75 + (model.box_max + model.box_min - 2 * centre).norm();

  Tr tr;
  C2t3 c2t3(tr);
  using Surface = CGAL::Implicit_surface_3<GT, HandFunction>;
  Surface surface(HandFunction{&model}, GT::Sphere_3(Point_3(centre.x(), centre.y(), centre.z()), radius * radius),
                  1e-7);
  CGAL::Surface_mesh_default_criteria_3<Tr> criteria(options.facet_angle_deg, options.facet_size_mm,
                                                     options.facet_distance_mm);
  CGAL::make_surface_mesh(c2t3, surface, criteria, CGAL::Manifold_tag(), 40);

  CGAL::Surface_mesh<Point_3> sm;
  CGAL::facets_in_complex_2_to_triangle_mesh(c2t3, sm);
  HS_CHECK(CGAL::is_closed(sm), "mesher produced an open surface");
  if (!CGAL::Polygon_mesh_processing::is_outward_oriented(sm)) CGAL::Polygon_mesh_processing::reverse_face_orientations(sm);

  HandMeshResult r;
  r.self_intersects = CGAL::Polygon_mesh_processing::does_self_intersect(sm);
  r.mesh = to_mesh(sm);
  r.health = mesh_health(r.mesh);
  HS_CHECK(r.health.closed() && r.health.manifold() && r.health.faces == sm.number_of_faces(),
           "meshed hand is not a closed manifold");
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace handskin
