#include "skin/baseline.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/compute_average_spacing.h>
#include <CGAL/poisson_surface_reconstruction.h>
#include <CGAL/Random.h>
#include <CGAL/property_map.h>

#include <chrono>
#include <utility>

#include "core/errors.hpp"
#include "mesh/from_cgal.hpp"

namespace handskin {

namespace {
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Pwn = std::pair<K::Point_3, K::Vector_3>;
}  // namespace

size_t thinning_step(size_t n, size_t max_points) {
  return std::max<size_t>(1, (n + max_points - 1) / std::max<size_t>(max_points, 1));
}

BaselineResult poisson_baseline(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& normals,
                                size_t max_points) {
  HS_CHECK(points.size() == normals.size(), "points and normals differ in length");
  const auto t0 = std::chrono::steady_clock::now();
  // CGAL's surface mesher draws its initial points from the default random, which is seeded
  // from the clock: fix it, as the hand mesher does, so a run repeats.
  CGAL::get_default_random() = CGAL::Random(1);
  BaselineResult r;
  std::vector<Pwn> pwn;
  const size_t step = thinning_step(points.size(), max_points);
  for (size_t i = 0; i < points.size(); i += step) {
    if (normals[i].squaredNorm() < 0.5) continue;  // samples without a normal cannot orient the field
    pwn.emplace_back(K::Point_3(points[i].x(), points[i].y(), points[i].z()),
                     K::Vector_3(normals[i].x(), normals[i].y(), normals[i].z()));
  }
  if (pwn.size() < 100) throw InputError("merged cloud", "too few oriented points for the Poisson baseline");
  r.points_used = pwn.size();
  r.average_spacing_mm = CGAL::compute_average_spacing<CGAL::Sequential_tag>(
      pwn, 6, CGAL::parameters::point_map(CGAL::First_of_pair_property_map<Pwn>()));
  CGAL::Surface_mesh<K::Point_3> sm;
  const bool ok = CGAL::poisson_surface_reconstruction_delaunay(
      pwn.begin(), pwn.end(), CGAL::First_of_pair_property_map<Pwn>(), CGAL::Second_of_pair_property_map<Pwn>(), sm,
      r.average_spacing_mm);
  HS_CHECK(ok && sm.number_of_faces() > 0, "CGAL Poisson reconstruction failed");
  r.mesh = to_trimesh(sm);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace handskin
