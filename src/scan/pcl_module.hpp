#pragma once
/// The interface of libhandskin_pcl.so (pcl_module.cpp): PCL's PLY and PCD readers and its
/// Poisson reconstruction, the parts of PCL whose libraries (pcl_io, pcl_surface) load VTK,
/// OpenNI, libusb, pcap and ~55 more: linked into the program they cost every command ~70 ms
/// and ~26 MB at its start; as a module they load at their first use (reading a .ply/.pcd
/// cloud, `skin.baseline`). Writing clouds needs no module (scan/cloud.cpp).
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

/// The module's entry points, loaded once; `failure` says why when they could not be.
struct PclModule {
  /// Reads `path` (PLY when `pcd` is 0, else PCD) into `blob`; 0, or nonzero with `error`.
  int (*read)(const char* path, int pcd, pcl::PCLPointCloud2* blob, std::string* error) = nullptr;
  /// Poisson-reconstructs `cloud` into `mesh`; 0, or nonzero with `error`.
  int (*poisson)(const pcl::PointCloud<pcl::PointNormal>::ConstPtr* cloud, const PoissonSettings* settings,
                 pcl::PolygonMesh* mesh, std::string* error) = nullptr;
  std::string failure;
};
const PclModule& pcl_module();

}  // namespace handskin

extern "C" {
int handskin_pcl_read(const char* path, int pcd, pcl::PCLPointCloud2* blob, std::string* error);
int handskin_pcl_poisson(const pcl::PointCloud<pcl::PointNormal>::ConstPtr* cloud, const handskin::PoissonSettings* settings,
                         pcl::PolygonMesh* mesh, std::string* error);
}
