#include "skin/baseline.hpp"

#include <pcl/PolygonMesh.h>
#include <pcl/conversions.h>
#include <pcl/point_types.h>

#include <chrono>

#include "core/errors.hpp"
#include "scan/pcl_module.hpp"

namespace handskin {

size_t thinning_step(size_t n, size_t max_points) {
  return std::max<size_t>(1, (n + max_points - 1) / std::max<size_t>(max_points, 1));
}

std::vector<Eigen::Vector3d> thinned_points(const std::vector<Eigen::Vector3d>& points, size_t max_points) {
  const size_t step = thinning_step(points.size(), max_points);
  std::vector<Eigen::Vector3d> out;
  out.reserve(points.size() / step + 1);
  for (size_t i = 0; i < points.size(); i += step) out.push_back(points[i]);
  return out;
}

BaselineResult poisson_baseline(const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& normals,
                                size_t max_points) {
  HS_CHECK(points.size() == normals.size(), "points and normals differ in length");
  const auto t0 = std::chrono::steady_clock::now();
  BaselineResult r;
  auto cloud = std::make_shared<pcl::PointCloud<pcl::PointNormal>>();
  const size_t step = thinning_step(points.size(), max_points);
  for (size_t i = 0; i < points.size(); i += step) {
    if (normals[i].squaredNorm() < 0.5) continue;  // samples without a normal cannot orient the field
    pcl::PointNormal p;
    p.x = static_cast<float>(points[i].x()), p.y = static_cast<float>(points[i].y()), p.z = static_cast<float>(points[i].z());
    p.normal_x = static_cast<float>(normals[i].x()), p.normal_y = static_cast<float>(normals[i].y()),
    p.normal_z = static_cast<float>(normals[i].z());
    cloud->push_back(p);
  }
  if (cloud->size() < 100) throw InputError("merged cloud", "too few oriented points for the Poisson baseline");
  r.points_used = cloud->size();
  // Kazhdan's screened Poisson as PCL ships it, on one thread: its parallel accumulation
  // changes the last bits between runs, and so the mesh. (CGAL's Poisson meshes its function
  // with the Surface_mesher, whose maps are keyed by memory addresses: it differs from run to
  // run too, CGAL issue #6240.) Depth 7 at scale 1.5 puts cells of ~2 mm on a hand. Through
  // handskin's PCL module (scan/pcl_module.hpp): pcl_surface is loaded only here.
  const PclModule& m = pcl_module("skin.baseline");
  PoissonSettings settings;  // depth 7, scale 1.5, one thread, manifold
  pcl::PolygonMesh pm;
  std::string error;
  const pcl::PointCloud<pcl::PointNormal>::ConstPtr input = cloud;
  if (m.poisson(&input, &settings, &pm, &error) != 0) throw InputError("skin.baseline", "Poisson reconstruction: " + error);
  pcl::PointCloud<pcl::PointXYZ> v;
  pcl::fromPCLPointCloud2(pm.cloud, v);
  HS_CHECK(!pm.polygons.empty() && !v.empty(), "Poisson reconstruction gave no surface");
  Mesh soup;
  for (const auto& p : v.points) soup.vertices.emplace_back(p.x, p.y, p.z);
  for (const auto& f : pm.polygons) {
    HS_CHECK(f.vertices.size() == 3, "Poisson reconstruction gave a non-triangle");
    soup.faces.push_back({static_cast<int>(f.vertices[0]), static_cast<int>(f.vertices[1]), static_cast<int>(f.vertices[2])});
  }
  r.mesh = manifold_faces(soup, &r.faces_dropped);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace handskin
