// libhandskin_pcl.so: the program's only use of pcl_io and pcl_surface (pcl_module.hpp says
// why they are a module). Exceptions stay inside: each entry point returns nonzero with the
// reason.
#include "scan/pcl_module.hpp"

#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <pcl/surface/poisson.h>

#include <exception>

extern "C" int handskin_pcl_read(const char* path, int pcd, pcl::PCLPointCloud2* blob, std::string* error) {
  try {
    int rc;
    if (pcd) {
      pcl::PCDReader reader;
      rc = reader.read(path, *blob);
    } else {
      pcl::PLYReader reader;
      rc = reader.read(path, *blob);
    }
    if (rc < 0) error->clear();
    return rc < 0 ? 1 : 0;
  } catch (const std::exception& e) {
    *error = e.what();
    return 1;
  }
}

extern "C" int handskin_pcl_poisson(const pcl::PointCloud<pcl::PointNormal>::ConstPtr* cloud,
                                    const handskin::PoissonSettings* settings, pcl::PolygonMesh* mesh,
                                    std::string* error) {
  try {
    pcl::Poisson<pcl::PointNormal> poisson;
    poisson.setDepth(settings->depth);
    poisson.setScale(settings->scale);
    poisson.setThreads(settings->threads);
    poisson.setManifold(settings->manifold);
    poisson.setOutputPolygons(false);
    poisson.setInputCloud(*cloud);
    poisson.reconstruct(*mesh);
    return 0;
  } catch (const std::exception& e) {
    *error = e.what();
    return 1;
  }
}

namespace {
template <typename PointT>
int voxel_grid(const typename pcl::PointCloud<PointT>::ConstPtr* cloud, float leaf, pcl::PointCloud<PointT>* out,
               std::string* error) {
  try {
    pcl::VoxelGrid<PointT> grid;
    grid.setInputCloud(*cloud);
    grid.setLeafSize(leaf, leaf, leaf);
    grid.filter(*out);
    return 0;
  } catch (const std::exception& e) {
    *error = e.what();
    return 1;
  }
}
}  // namespace

extern "C" int handskin_pcl_voxel_grid_xyz(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr* cloud, float leaf,
                                           pcl::PointCloud<pcl::PointXYZ>* out, std::string* error) {
  return voxel_grid<pcl::PointXYZ>(cloud, leaf, out, error);
}

extern "C" int handskin_pcl_voxel_grid_normals(const pcl::PointCloud<pcl::PointNormal>::ConstPtr* cloud, float leaf,
                                               pcl::PointCloud<pcl::PointNormal>* out, std::string* error) {
  return voxel_grid<pcl::PointNormal>(cloud, leaf, out, error);
}
