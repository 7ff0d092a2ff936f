#pragma once
/// The triangle mesh that stages exchange — plain arrays, like every other stage result — its
/// file I/O and its health checks. OpenMesh (files, half-edge topology) and CGAL (trees,
/// exact predicates, the mesher) are used inside mesh/ and inside the stages that need them;
/// neither crosses a stage border.
#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace handskin {

/// Vertex positions (mm) and faces as vertex-index triples, counter-clockwise seen from
/// outside for a closed, outward-oriented surface.
struct Mesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::array<int, 3>> faces;
  size_t n_vertices() const { return vertices.size(); }
  size_t n_faces() const { return faces.size(); }
};

/// Read a triangle mesh (.ply, .obj, .off, .stl) with OpenMesh's readers. Throws InputError
/// naming the file when it cannot be read, has no faces, or holds non-finite coordinates.
Mesh load_mesh(const std::string& path);
/// What OpenMesh's reader makes of a file, unchecked (faces may be none, coordinates may be
/// non-finite); nullopt when the reader fails. Its exceptions pass through. For readers that
/// take a mesh file's vertices as a point cloud.
std::optional<Mesh> read_mesh_file(const std::string& path);
/// Write by extension (.ply binary, .obj, .off, .stl binary), atomically, with OpenMesh's
/// writers: a face OpenMesh cannot add (a non-manifold edge or vertex) is not written.
void save_mesh(const std::string& path, const Mesh& mesh);

/// Wavefront OBJ text of `mesh` with a normal per vertex (`vn`, area-weighted) and, when
/// `corner_uv` is given (per face, its corners' (u, v) in glTF's convention: v down from the
/// image's first row), texture coordinates (`vt`, v up as OBJ has it; one per distinct corner
/// value); `mtllib` (when not empty) names a material library whose material "skin" the faces
/// use. Written here rather than by OpenMesh: the coordinates are per corner (two charts meet
/// at seams), which OpenMesh's writer takes only through half-edge properties.
std::string obj_text(const Mesh& mesh, const std::vector<std::array<Eigen::Vector2f, 3>>* corner_uv = nullptr,
                     const std::string& mtllib = "");

/// The faces OpenMesh's half-edge structure can take, added in order (a face that would make
/// an edge or a vertex non-manifold is left out and counted in `dropped`).
Mesh manifold_faces(const Mesh& mesh, size_t* dropped);

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
/// Measured on the mesh as OpenMesh's half-edge structure holds it (faces it cannot add are
/// left out, as in save_mesh).
MeshHealth mesh_health(const Mesh& mesh);

/// Unit vertex normals of a triangle soup, area-weighted (the sum of the faces' cross
/// products); +Z for a vertex in no face or whose faces cancel.
std::vector<Eigen::Vector3d> vertex_normals(const std::vector<Eigen::Vector3d>& vertices,
                                            const std::vector<std::array<int, 3>>& faces);
/// OpenMesh's vertex normals (update_normals: the normalised sum of the adjacent faces' unit
/// normals), the shading normals of the pictures.
std::vector<Eigen::Vector3d> shading_normals(const Mesh& mesh);

}  // namespace handskin
