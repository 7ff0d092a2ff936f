#include "mesh/mesh_check.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

#include <iterator>
#include <sstream>
#include <vector>

#include "core/atomic_file.hpp"

namespace handskin {

namespace {
// "element vertex N" / "element face N" of a PLY header; 0 when absent or not a PLY.
void ply_counts(const std::string& bytes, size_t* vertices, size_t* faces) {
  if (bytes.rfind("ply", 0) != 0) return;
  const size_t end = bytes.find("end_header");
  std::istringstream head(bytes.substr(0, end == std::string::npos ? 0 : end));
  std::string line;
  while (std::getline(head, line)) {
    std::istringstream w(line);
    std::string a, b;
    size_t n = 0;
    if (w >> a >> b >> n && a == "element") {
      if (b == "vertex") *vertices = n;
      if (b == "face") *faces = n;
    }
  }
}
}  // namespace

std::vector<std::array<int, 2>> crossing_face_pairs(const std::vector<Eigen::Vector3d>& v,
                                                    const std::vector<std::array<int, 3>>& faces) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using SM = CGAL::Surface_mesh<K::Point_3>;
  SM m;
  std::vector<SM::Vertex_index> h;
  h.reserve(v.size());
  for (const auto& p : v) h.push_back(m.add_vertex(K::Point_3(p.x(), p.y(), p.z())));
  for (const auto& f : faces) m.add_face(h[f[0]], h[f[1]], h[f[2]]);
  std::vector<std::pair<SM::Face_index, SM::Face_index>> pairs;
  CGAL::Polygon_mesh_processing::self_intersections(m, std::back_inserter(pairs));
  std::vector<std::array<int, 2>> out;
  out.reserve(pairs.size());
  for (const auto& [f, g] : pairs) out.push_back({static_cast<int>(f.idx()), static_cast<int>(g.idx())});
  return out;
}

WrittenMeshCheck check_written_mesh(const std::string& path) {
  WrittenMeshCheck c;
  c.path = path;
  const std::string bytes = read_file(path);
  ply_counts(bytes, &c.declared_vertices, &c.declared_faces);
  c.mesh = load_mesh(path);
  c.health = mesh_health(c.mesh);
  if (c.declared_faces > c.mesh.n_faces()) c.faces_dropped = c.declared_faces - c.mesh.n_faces();
  if (c.declared_vertices > 0 && c.mesh.n_vertices() > c.declared_vertices)
    c.vertices_split = c.mesh.n_vertices() - c.declared_vertices;
  c.crossing_pairs = crossing_face_pairs(c.mesh.vertices, c.mesh.faces).size();
  return c;
}

}  // namespace handskin
