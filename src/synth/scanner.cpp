#include "synth/scanner.hpp"


#include <cmath>

#include "core/errors.hpp"
#include "mesh/triangle_tree.hpp"
#include "core/random.hpp"

namespace handskin {

namespace {
using cgal::K;
constexpr double kDeg = M_PI / 180.0;
}  // namespace

bool ScannerOptions::IsValid(std::string* error) const {
  if (scanlines < 2 || scanlines > 4096 || points < 2 || points > 4096) return invalid(error, "scanlines/points must be in [2, 4096]");
  if (!(x_extent_mm > 0 && y_extent_mm > 0 && z_extent_mm > 0)) return invalid(error, "extents must be > 0");
  if (!(z_step_mm > 0) || z_extent_mm / z_step_mm > 65535) return invalid(error, "z_step_mm must be > 0 and fit 16 bits");
  if (!(table_height_mm > z_step_mm && table_height_mm < z_extent_mm)) return invalid(error, "table_height_mm must be inside the range");
  if (!(std::abs(table_tilt_deg) <= 10)) return invalid(error, "table_tilt_deg must be within ±10");
  if (!(laser_tilt_deg >= 0 && laser_tilt_deg < 60)) return invalid(error, "laser_tilt_deg must be in [0, 60)");
  if (!(max_incidence_deg > 0 && max_incidence_deg < 90)) return invalid(error, "max_incidence_deg must be in (0, 90)");
  if (!(noise_sigma_mm >= 0 && noise_sigma_mm < 5)) return invalid(error, "noise_sigma_mm must be in [0, 5)");
  return true;
}

double ScannerOptions::table_z(double x) const {
  return table_height_mm + std::tan(table_tilt_deg * kDeg) * (x - 0.5 * x_extent_mm);
}

Eigen::Vector3d ScannerOptions::laser_direction() const {
  return {std::sin(laser_tilt_deg * kDeg), 0.0, std::cos(laser_tilt_deg * kDeg)};
}

void Scene::add(const std::vector<Eigen::Vector3d>& v, const std::vector<std::array<int, 3>>& f, int object) {
  const int base = static_cast<int>(vertices.size());
  vertices.insert(vertices.end(), v.begin(), v.end());
  for (const auto& t : f) {
    faces.push_back({t[0] + base, t[1] + base, t[2] + base});
    face_object.push_back(object);
  }
}

ScanSimulation simulate_scan(const Scene& scene, const ScannerOptions& o, ScanSide side, std::uint64_t seed) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("scanner options", err);
  HS_CHECK(scene.faces.size() == scene.face_object.size(), "scene face tags disagree with faces");

  const cgal::TriangleTree tt(scene.vertices, scene.faces);
  const cgal::Tree& tree = tt.tree;
  const std::vector<cgal::Triangle>& tris = tt.triangles;

  ScanSimulation sim;
  ScanMeta& m = sim.scan.meta;
  m.scanlines = o.scanlines;
  m.points = o.points;
  m.x_origin_mm = 0;
  m.x_step_mm = o.x_step();
  m.y_origin_mm = 0;
  m.y_step_mm = o.y_step();
  m.z_origin_mm = 0;
  m.z_step_mm = o.z_step_mm;
  m.side = side;
  m.device = "handskin synthetic CUBIST";
  const size_t n = static_cast<size_t>(o.scanlines) * o.points;
  std::vector<double> height(n, 0.0);
  sim.pixel_object.assign(n, kPixelNoReturn);
  sim.camera_face.assign(n, -1);
  sim.camera_z.assign(n, 0.f);
  std::vector<char> shadowed(n, 0), steep(n, 0);

  const Eigen::Vector3d L = o.laser_direction();
  const K::Vector_3 Lk(L.x(), L.y(), L.z());
  const double cos_max = std::cos(o.max_incidence_deg * kDeg);
  const double tilt = o.table_tilt_deg * kDeg;
  const Eigen::Vector3d table_normal(-std::sin(tilt), 0.0, std::cos(tilt));
  const double top = o.z_extent_mm + 50.0;

#pragma omp parallel for schedule(dynamic, 4)
  for (int i = 0; i < o.scanlines; ++i) {
    for (int j = 0; j < o.points; ++j) {
      const size_t idx = static_cast<size_t>(i) * o.points + j;
      const double x = i * m.x_step_mm, y = j * m.y_step_mm;
      const K::Ray_3 down(K::Point_3(x, y, top), K::Vector_3(0, 0, -1));
      Eigen::Vector3d p, nrm;
      int object = kPixelTable;
      const auto hit = tree.first_intersection(down);
      const K::Point_3* hp = hit ? boost::get<K::Point_3>(&hit->first) : nullptr;
      if (hp && hp->z() > o.table_z(x)) {
        p = {hp->x(), hp->y(), hp->z()};
        const cgal::Triangle& t = *hit->second;
        const K::Vector_3 nk = CGAL::cross_product(t[1] - t[0], t[2] - t[0]);
        nrm = Eigen::Vector3d(nk.x(), nk.y(), nk.z()).normalized();
        if (nrm.z() < 0) nrm = -nrm;  // seen from above: the side facing the camera
        const auto face = hit->second - tris.begin();
        object = scene.face_object[static_cast<size_t>(face)];
        sim.camera_face[idx] = static_cast<int>(face);
        sim.camera_z[idx] = static_cast<float>(p.z());
      } else {
        p = {x, y, o.table_z(x)};
        nrm = table_normal;
      }
      if (nrm.z() < cos_max || nrm.dot(L) < cos_max) {
        steep[idx] = 1;
        continue;
      }
      const Eigen::Vector3d q = p + 1e-3 * nrm + 1e-3 * L;
      if (tree.do_intersect(K::Ray_3(K::Point_3(q.x(), q.y(), q.z()), Lk))) {
        shadowed[idx] = 1;
        continue;
      }
      height[idx] = p.z();
      sim.pixel_object[idx] = object;
    }
  }

  // Noise and quantisation, drawn in pixel order so results do not depend on threads.
  Rng rng(seed);
  sim.scan.values.assign(n, 0);
  int max_object = -1;
  for (int ob : scene.face_object) max_object = std::max(max_object, ob);
  sim.returns_per_object.assign(static_cast<size_t>(max_object + 1), 0);
  for (size_t idx = 0; idx < n; ++idx) {
    const double noise = o.noise_sigma_mm * rng.normal();
    sim.shadowed += shadowed[idx];
    sim.too_steep += steep[idx];
    if (sim.pixel_object[idx] == kPixelNoReturn) continue;
    const double v = std::round((height[idx] + noise - m.z_origin_mm) / m.z_step_mm);
    if (v < 1 || v > 65535 || height[idx] > o.z_extent_mm) {  // out of the measuring range
      sim.pixel_object[idx] = kPixelNoReturn;
      continue;
    }
    sim.scan.values[idx] = static_cast<std::uint16_t>(v);
    if (sim.pixel_object[idx] >= 0) ++sim.returns_per_object[static_cast<size_t>(sim.pixel_object[idx])];
  }
  return sim;
}

}  // namespace handskin
