#pragma once
/// Checks of a mesh file as written: what the report's quality gates say of a skin is
/// measured here, on the file read back, not on the mesh in memory before it was written.
#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "mesh/mesh.hpp"

namespace handskin {

struct WrittenMeshCheck {
  std::string path;
  Mesh mesh;                         ///< the file as read back
  MeshHealth health;                 ///< of the mesh read back
  size_t declared_vertices = 0, declared_faces = 0;  ///< as the PLY header says (0 for other formats)
  size_t faces_dropped = 0;          ///< faces the reader could not add (non-manifold edges)
  size_t vertices_split = 0;         ///< vertices the reader had to duplicate to add a face (non-manifold)
  size_t crossing_pairs = 0;         ///< pairs of triangles that cross (CGAL's exact predicates)
  bool closed() const { return health.closed() && faces_dropped == 0; }
  bool manifold() const { return health.manifold() && faces_dropped == 0 && vertices_split == 0; }
  bool outward() const { return health.volume_mm3 > 0; }
  bool self_intersects() const { return crossing_pairs > 0; }
  bool watertight() const { return closed() && manifold() && health.components == 1 && outward() && !self_intersects(); }
};

/// Read `path` back and check it: closed, manifold, one component, outward, no two triangles
/// crossing (CGAL::Polygon_mesh_processing::self_intersections, exact predicates, on the
/// coordinates as stored). Throws InputError when the file cannot be read.
WrittenMeshCheck check_written_mesh(const std::string& path);

/// Every pair of faces that cross (CGAL's self-intersection test, exact predicates; faces
/// sharing a vertex or an edge count only if they overlap beyond it), as face indices. The
/// CGAL mesh is built face by face from the indices given (no repair): the triangles tested are
/// these.
std::vector<std::array<int, 2>> crossing_face_pairs(const std::vector<Eigen::Vector3d>& vertices,
                                                    const std::vector<std::array<int, 3>>& faces);

/// crossing_face_pairs for one mesh whose vertices move: the CGAL mesh built once, and after a
/// move of some vertices only the faces that can have changed tested again (the faces around
/// the moved vertices and every face whose box meets one of theirs), the rest of the pairs
/// kept. The pairs are those crossing_face_pairs gives, in another order.
class CrossingFaces {
 public:
  CrossingFaces(const std::vector<Eigen::Vector3d>& vertices, const std::vector<std::array<int, 3>>& faces);
  ~CrossingFaces();
  CrossingFaces(const CrossingFaces&) = delete;
  CrossingFaces& operator=(const CrossingFaces&) = delete;
  /// Every crossing pair at the positions given at construction.
  const std::vector<std::array<int, 2>>& pairs() const { return pairs_; }
  /// The vertices `moved` now lie at vertices[moved[k]] (the others where they were): the pairs again.
  const std::vector<std::array<int, 2>>& move(const std::vector<Eigen::Vector3d>& vertices, const std::vector<int>& moved);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<std::array<int, 2>> pairs_;
};

}  // namespace handskin
