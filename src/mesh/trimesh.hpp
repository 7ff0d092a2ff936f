#pragma once
/// The triangle mesh passed between stages (OpenMesh), its file I/O and its health checks.
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>

#include <Eigen/Core>
#include <array>
#include <vector>

#include <string>

namespace handskin {

struct MeshTraits : public OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;
  using Normal = OpenMesh::Vec3d;
};
using TriMesh = OpenMesh::TriMesh_ArrayKernelT<MeshTraits>;

/// Read a triangle mesh (.ply, .obj, .off, .stl). Throws InputError naming the file when it
/// cannot be read, has no faces, or holds non-finite coordinates.
TriMesh load_mesh(const std::string& path);
/// Write by extension (.ply binary, .obj, .off, .stl binary), atomically.
void save_mesh(const std::string& path, const TriMesh& mesh);

struct MeshHealth {
  size_t vertices = 0, faces = 0;
  size_t boundary_edges = 0;         ///< 0 for a closed mesh
  size_t nonmanifold_vertices = 0;   ///< vertices whose one-ring is not a single fan
  size_t components = 0;             ///< face-connected components
  double volume_mm3 = 0;             ///< signed; > 0 when faces are oriented outward
  double area_mm2 = 0;
  bool closed() const { return boundary_edges == 0; }
  bool manifold() const { return nonmanifold_vertices == 0; }
};
MeshHealth mesh_health(const TriMesh& mesh);

/// The mesh as plain arrays (vertex positions, mm; faces as vertex-index triples), for code
/// that works on triangle soups: CGAL trees, the scanner's scene, distances.
std::vector<Eigen::Vector3d> mesh_vertices(const TriMesh& mesh);
std::vector<std::array<int, 3>> mesh_faces(const TriMesh& mesh);
/// The inverse: a mesh from positions and vertex-index triples (vertex order kept).
TriMesh mesh_from_arrays(const std::vector<Eigen::Vector3d>& vertices, const std::vector<std::array<int, 3>>& faces);
/// Unit vertex normals of a triangle soup, area-weighted (the sum of the faces' cross
/// products); +Z for a vertex in no face or whose faces cancel.
std::vector<Eigen::Vector3d> vertex_normals(const std::vector<Eigen::Vector3d>& vertices,
                                            const std::vector<std::array<int, 3>>& faces);

}  // namespace handskin
