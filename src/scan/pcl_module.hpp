#pragma once
/// The interface of libhandskin_pcl.so (pcl_module.cpp): PCL's PLY and PCD readers, its voxel
/// grid and its Poisson reconstruction, the parts of PCL whose libraries (pcl_io, pcl_surface,
/// pcl_filters) load VTK, OpenNI, libusb, pcap and ~55 more and relocate the most symbols:
/// linked into the program they cost every command ~0.1 s and ~38 MB at its start; as a module
/// they load at their first use (reading a .ply/.pcd cloud, a cloud from another scanner made
/// ready, `skin.baseline`). Writing clouds needs no module (scan/cloud.cpp).
///
/// The entry points take C++ types (module and program are built together, by one compiler).
#include <pcl/PCLPointCloud2.h>
#include <pcl/PolygonMesh.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <string>

namespace handskin {

/// PCL's screened Poisson settings (skin/baseline.cpp says why these).
struct PoissonSettings {
  int depth = 7;
  float scale = 1.5f;
  int threads = 1;
  bool manifold = true;
};

/// The module's entry points (pcl_module() loads them once).
struct PclModule {
  /// Reads `path` (PLY when `pcd` is 0, else PCD) into `blob`; 0, or nonzero with `error`.
  int (*read)(const char* path, int pcd, pcl::PCLPointCloud2* blob, std::string* error) = nullptr;
  /// Poisson-reconstructs `cloud` into `mesh`; 0, or nonzero with `error`.
  int (*poisson)(const pcl::PointCloud<pcl::PointNormal>::ConstPtr* cloud, const PoissonSettings* settings,
                 pcl::PolygonMesh* mesh, std::string* error) = nullptr;
  /// PCL's VoxelGrid at `leaf` mm: each voxel's points (and normals) averaged; 0, or nonzero with `error`.
  int (*voxel_grid_xyz)(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr* cloud, float leaf,
                        pcl::PointCloud<pcl::PointXYZ>* out, std::string* error) = nullptr;
  int (*voxel_grid_normals)(const pcl::PointCloud<pcl::PointNormal>::ConstPtr* cloud, float leaf,
                            pcl::PointCloud<pcl::PointNormal>* out, std::string* error) = nullptr;
};
/// The module, loaded at the first call; throws InputError naming `needed_by` (a file, a
/// pipeline key) when it cannot be loaded.
const PclModule& pcl_module(const std::string& needed_by);

/// PCL's VoxelGrid through the module; throws InputError naming `needed_by` when it fails.
pcl::PointCloud<pcl::PointXYZ> voxel_grid(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& cloud, float leaf,
                                          const std::string& needed_by);
pcl::PointCloud<pcl::PointNormal> voxel_grid(const pcl::PointCloud<pcl::PointNormal>::ConstPtr& cloud, float leaf,
                                             const std::string& needed_by);

}  // namespace handskin

extern "C" {
int handskin_pcl_read(const char* path, int pcd, pcl::PCLPointCloud2* blob, std::string* error);
int handskin_pcl_poisson(const pcl::PointCloud<pcl::PointNormal>::ConstPtr* cloud, const handskin::PoissonSettings* settings,
                         pcl::PolygonMesh* mesh, std::string* error);
int handskin_pcl_voxel_grid_xyz(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr* cloud, float leaf,
                                pcl::PointCloud<pcl::PointXYZ>* out, std::string* error);
int handskin_pcl_voxel_grid_normals(const pcl::PointCloud<pcl::PointNormal>::ConstPtr* cloud, float leaf,
                                    pcl::PointCloud<pcl::PointNormal>* out, std::string* error);
}
