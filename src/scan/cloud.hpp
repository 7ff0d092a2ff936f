#pragma once
/// Point clouds (PCL) from range scans, and PLY/PCD I/O so scans from other devices can
/// enter the pipeline.
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <string>
#include <vector>

#include <Eigen/Core>

#include "scan/cloud_file.hpp"
#include "scan/cubist_io.hpp"

namespace handskin {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;

/// Organised cloud in the scan's own frame (mm): width = points, height = scanlines,
/// `cloud.at(j, i)` is sample (i, j); no-return samples are NaN (is_dense = false).
Cloud::Ptr scan_to_organized_cloud(const RangeScan& scan);
/// The same points without the no-return samples (scanline order kept).
Cloud::Ptr dense_copy(const Cloud& cloud);

/// Rasterise a cloud in a scanner frame into a range image on `meta`'s grid: each point goes
/// to its nearest sample, the highest point of a sample wins (the view from above), heights
/// are quantised to `z_step_mm`. Points off the grid or outside the 16-bit height range are
/// dropped and counted in `*dropped` (if given). Inverse of scan_to_organized_cloud.
RangeScan cloud_to_scan(const Cloud& cloud, const ScanMeta& meta, size_t* dropped = nullptr);

/// Load a cloud's points (.ply, .pcd, or .xyz/.pts/.txt text) through read_point_cloud (an
/// organised cloud's NaN points, its no-returns, are dropped). Throws InputError naming the file
/// when it cannot be read, has another extension, holds no points or a non-finite coordinate
/// elsewhere.
Cloud::Ptr load_cloud(const std::string& path);
/// A cloud file by its extension as load_cloud reads it: .ply, .pcd, .xyz, .pts or .txt.
bool is_cloud_file(const std::string& path);
/// The same file as read_point_cloud reads it: its normals and labels too (`convert`).
PointCloudFile load_cloud_file(const std::string& path);
/// Save as binary PLY or PCD by extension, atomically: x y z as floats (the project's one
/// writer of clouds; not through pcl_io, see pcl_module.hpp).
void save_cloud(const std::string& path, const Cloud& cloud);
/// The same for the merged cloud's points: x y z, the normal (PLY nx ny nz, PCD normal_x …)
/// as floats, the side label as uint.
void save_cloud(const std::string& path, const pcl::PointCloud<pcl::PointXYZLNormal>& cloud);
/// The same for a list of points (mm, or whatever units they are in): x y z.
void save_cloud(const std::string& path, const std::vector<Eigen::Vector3d>& points);
/// The same for a cloud file read (`convert`): x y z, and what it has of the normal and the
/// label (a merged.ply's side), so that a cloud converted to the other format loses neither.
void save_cloud_file(const std::string& path, const PointCloudFile& file);

/// PCL's console messages off: every failure of ours is one line that names the file.
void silence_pcl_console();

}  // namespace handskin
