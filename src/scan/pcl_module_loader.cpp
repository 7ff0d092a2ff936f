#include "core/errors.hpp"
#include "core/module.hpp"
#include "scan/pcl_module.hpp"

namespace handskin {

namespace {
struct Loaded {
  PclModule entry;
  std::string failure;
};
const Loaded& loaded() {
  static const Loaded m = [] {
    Loaded m;
    LoadedModule lib = open_module(HANDSKIN_PCL_MODULE, "libhandskin_pcl.so");
    PclModule& e = m.entry;
    lib.entry(e.read, "handskin_pcl_read");
    lib.entry(e.poisson, "handskin_pcl_poisson");
    lib.entry(e.voxel_grid_xyz, "handskin_pcl_voxel_grid_xyz");
    lib.entry(e.voxel_grid_normals, "handskin_pcl_voxel_grid_normals");
    m.failure = lib.failure;
    return m;
  }();
  return m;
}
}  // namespace

const PclModule& pcl_module(const std::string& needed_by) {
  const Loaded& m = loaded();
  if (!m.failure.empty())
    throw InputError(needed_by, "needs handskin's PCL module (libhandskin_pcl.so: PCL's readers, voxel grid and "
                                "Poisson), which could not be loaded: " + m.failure);
  return m.entry;
}

namespace {
// One of the module's voxel grids (`entry`), its failure an InputError naming `needed_by`.
template <typename PointT, typename Entry>
pcl::PointCloud<PointT> voxel_grid_by(Entry entry, const typename pcl::PointCloud<PointT>::ConstPtr& cloud, float leaf,
                                      const std::string& needed_by) {
  pcl::PointCloud<PointT> out;
  std::string error;
  if (entry(&cloud, leaf, &out, &error) != 0) throw InputError(needed_by, "voxel grid: " + error);
  return out;
}
}  // namespace

pcl::PointCloud<pcl::PointXYZ> voxel_grid(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& cloud, float leaf,
                                          const std::string& needed_by) {
  return voxel_grid_by<pcl::PointXYZ>(pcl_module(needed_by).voxel_grid_xyz, cloud, leaf, needed_by);
}

pcl::PointCloud<pcl::PointNormal> voxel_grid(const pcl::PointCloud<pcl::PointNormal>::ConstPtr& cloud, float leaf,
                                             const std::string& needed_by) {
  return voxel_grid_by<pcl::PointNormal>(pcl_module(needed_by).voxel_grid_normals, cloud, leaf, needed_by);
}

}  // namespace handskin
