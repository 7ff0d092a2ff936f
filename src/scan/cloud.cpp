#include "scan/cloud.hpp"

#include <pcl/console/print.h>

#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/paths.hpp"
#include "scan/cloud_file.hpp"

namespace handskin {


Cloud::Ptr scan_to_organized_cloud(const RangeScan& scan) {
  auto cloud = std::make_shared<Cloud>();
  cloud->width = static_cast<std::uint32_t>(scan.meta.points);
  cloud->height = static_cast<std::uint32_t>(scan.meta.scanlines);
  cloud->is_dense = false;
  cloud->points.resize(static_cast<size_t>(cloud->width) * cloud->height);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int i = 0; i < scan.meta.scanlines; ++i)
    for (int j = 0; j < scan.meta.points; ++j) {
      pcl::PointXYZ& p = cloud->at(j, i);
      if (scan.valid(i, j)) {
        const Eigen::Vector3d q = scan.position(i, j);
        p.x = static_cast<float>(q.x());
        p.y = static_cast<float>(q.y());
        p.z = static_cast<float>(q.z());
      } else {
        p.x = p.y = p.z = nan;
      }
    }
  return cloud;
}

Cloud::Ptr dense_copy(const Cloud& cloud) {
  auto out = std::make_shared<Cloud>();
  out->reserve(cloud.size());
  for (const auto& p : cloud.points)
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) out->push_back(p);
  out->width = static_cast<std::uint32_t>(out->size());
  out->height = 1;
  out->is_dense = true;
  return out;
}

RangeScan cloud_to_scan(const Cloud& cloud, const ScanMeta& meta, size_t* dropped) {
  RangeScan scan;
  scan.meta = meta;
  scan.values.assign(static_cast<size_t>(meta.scanlines) * meta.points, 0);
  size_t lost = 0;
  for (const auto& p : cloud.points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    const long i = std::lround((p.x - meta.x_origin_mm) / meta.x_step_mm);
    const long j = std::lround((p.y - meta.y_origin_mm) / meta.y_step_mm);
    const long v = std::lround((p.z - meta.z_origin_mm) / meta.z_step_mm);
    if (i < 0 || j < 0 || i >= meta.scanlines || j >= meta.points || v < 1 || v > 65535) {
      ++lost;
      continue;
    }
    auto& cell = scan.values[static_cast<size_t>(i) * meta.points + static_cast<size_t>(j)];
    cell = std::max(cell, static_cast<std::uint16_t>(v));
  }
  if (dropped) *dropped = lost;
  return scan;
}

namespace {
// The extension of a cloud file handskin reads or writes as PCL's own formats.
std::string ply_or_pcd(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext != ".ply" && ext != ".pcd") throw InputError(path, "unknown point-cloud extension (use .ply or .pcd)");
  return ext;
}

Cloud cloud_of(const std::vector<Eigen::Vector3d>& points) {
  Cloud c;
  c.reserve(points.size());
  for (const auto& p : points) c.push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())));
  return c;  // push_back keeps width = size, height = 1, dense
}

template <typename PointT>
void save_any_cloud(const std::string& path, const pcl::PointCloud<PointT>& cloud) {
  const std::string ext = ply_or_pcd(path);
  write_via_temp(path, [&](const std::string& tmp) {
    const int rc = ext == ".ply" ? pcl::io::savePLYFileBinary(tmp, cloud) : pcl::io::savePCDFileBinary(tmp, cloud);
    if (rc < 0) throw InputError(path, "cannot write point cloud");
  });
}
}  // namespace

Cloud::Ptr load_cloud(const std::string& path) {
  ply_or_pcd(path);
  return std::make_shared<Cloud>(cloud_of(read_point_cloud(path).points));
}

void save_cloud(const std::string& path, const Cloud& cloud) { save_any_cloud(path, cloud); }
void save_cloud(const std::string& path, const pcl::PointCloud<pcl::PointXYZLNormal>& cloud) {
  save_any_cloud(path, cloud);
}
void save_cloud(const std::string& path, const std::vector<Eigen::Vector3d>& points) { save_any_cloud(path, cloud_of(points)); }

void silence_pcl_console() { pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS); }

}  // namespace handskin
