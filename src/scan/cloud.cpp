#include "scan/cloud.hpp"

#include <pcl/console/print.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <type_traits>
#include <cmath>
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

// A cloud as a binary PLY or PCD file's bytes: x y z, and for the merged cloud's points the
// normal and the side label. Written here rather than through pcl_io: each format is a header
// and the points' bytes, and linking pcl_io would load ~60 more libraries into every command
// (pcl_module.hpp). PCL's readers read both (tests/test_formats.cpp, Clouds.*).
template <typename PointT>
std::string cloud_file_bytes(const pcl::PointCloud<PointT>& cloud, bool ply) {
  static_assert(std::numeric_limits<float>::is_iec559 && sizeof(float) == 4, "PLY and PCD store IEEE floats");
  const std::uint16_t probe = 1;
  HS_CHECK(*reinterpret_cast<const unsigned char*>(&probe) == 1, "the cloud writers assume a little-endian machine");
  constexpr bool labelled = std::is_same_v<PointT, pcl::PointXYZLNormal>;
  constexpr bool oriented = labelled || std::is_same_v<PointT, pcl::PointNormal>;
  // (PLY name, PCD name, PCD type) per 4-byte field.
  std::vector<std::array<const char*, 3>> fields = {{"x", "x", "F"}, {"y", "y", "F"}, {"z", "z", "F"}};
  if (oriented) fields.insert(fields.end(), {{"nx", "normal_x", "F"}, {"ny", "normal_y", "F"}, {"nz", "normal_z", "F"}});
  if (labelled) fields.push_back({"label", "label", "U"});
  const size_t n = cloud.size();
  // An organised cloud (a scan's grid, its no-returns NaN) keeps its rows: PCD's WIDTH and
  // HEIGHT, PLY's obj_info num_cols / num_rows as PCL's reader and writer name them.
  const bool organised = cloud.height > 1 && static_cast<size_t>(cloud.width) * cloud.height == n;
  std::string h;
  if (ply) {
    h = "ply\nformat binary_little_endian 1.0\ncomment handskin\n";
    if (organised)
      h += "obj_info num_cols " + std::to_string(cloud.width) + "\nobj_info num_rows " + std::to_string(cloud.height) + "\n";
    h += "element vertex " + std::to_string(n) + "\n";
    for (const auto& f : fields) h += std::string("property ") + (f[2][0] == 'U' ? "uint " : "float ") + f[0] + "\n";
    h += "end_header\n";
  } else {
    std::string names, sizes, types, counts;
    for (const auto& f : fields) names += std::string(" ") + f[1], sizes += " 4", types += std::string(" ") + f[2], counts += " 1";
    h = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS" + names + "\nSIZE" + sizes + "\nTYPE" + types +
        "\nCOUNT" + counts + "\nWIDTH " + std::to_string(organised ? cloud.width : n) + "\nHEIGHT " +
        std::to_string(organised ? cloud.height : 1) + "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(n) +
        "\nDATA binary\n";
  }
  std::string out = h;
  out.resize(h.size() + n * fields.size() * 4);
  char* w = out.data() + h.size();
  const auto put = [&w](auto v) {
    static_assert(sizeof v == 4);
    std::memcpy(w, &v, 4);
    w += 4;
  };
  for (const PointT& p : cloud.points) {
    put(p.x), put(p.y), put(p.z);
    if constexpr (oriented) put(p.normal_x), put(p.normal_y), put(p.normal_z);
    if constexpr (labelled) put(static_cast<std::uint32_t>(p.label));
  }
  return out;
}

template <typename PointT>
void save_any_cloud(const std::string& path, const pcl::PointCloud<PointT>& cloud) {
  write_file_atomic(path, cloud_file_bytes(cloud, ply_or_pcd(path) == ".ply"));
}
}  // namespace

bool is_cloud_file(const std::string& path) {
  const std::string ext = lower_extension(path);
  return ext == ".ply" || ext == ".pcd" || ext == ".xyz" || ext == ".pts" || ext == ".txt";
}

PointCloudFile load_cloud_file(const std::string& path) {
  if (!is_cloud_file(path)) throw InputError(path, "unknown point-cloud extension (use .ply, .pcd, .xyz, .pts or .txt)");
  return read_point_cloud(path);
}

Cloud::Ptr load_cloud(const std::string& path) { return std::make_shared<Cloud>(cloud_of(load_cloud_file(path).points)); }

void save_cloud_file(const std::string& path, const PointCloudFile& file) {
  if (file.normals.empty()) return save_cloud(path, file.points);
  HS_CHECK(file.normals.size() == file.points.size() && (file.labels.empty() || file.labels.size() == file.points.size()),
           "a cloud's normals and labels are one per point");
  const auto fill = [&](auto* cloud) {
    cloud->resize(file.points.size());
    for (size_t k = 0; k < file.points.size(); ++k) {
      auto& q = (*cloud)[k];
      q.x = static_cast<float>(file.points[k].x()), q.y = static_cast<float>(file.points[k].y()), q.z = static_cast<float>(file.points[k].z());
      q.normal_x = static_cast<float>(file.normals[k].x()), q.normal_y = static_cast<float>(file.normals[k].y());
      q.normal_z = static_cast<float>(file.normals[k].z());
    }
  };
  if (!file.labels.empty()) {
    pcl::PointCloud<pcl::PointXYZLNormal> c;
    fill(&c);
    for (size_t k = 0; k < file.points.size(); ++k) c[k].label = file.labels[k];
    return save_any_cloud(path, c);
  }
  pcl::PointCloud<pcl::PointNormal> c;
  fill(&c);
  save_any_cloud(path, c);
}

void save_cloud(const std::string& path, const Cloud& cloud) { save_any_cloud(path, cloud); }
void save_cloud(const std::string& path, const pcl::PointCloud<pcl::PointXYZLNormal>& cloud) {
  save_any_cloud(path, cloud);
}
void save_cloud(const std::string& path, const std::vector<Eigen::Vector3d>& points) { save_any_cloud(path, cloud_of(points)); }

void silence_pcl_console() { pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS); }

}  // namespace handskin
