#include "mesh/mesh_check.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/box_intersection_d.h>

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

namespace {
using CheckKernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using CheckMesh = CGAL::Surface_mesh<CheckKernel::Point_3>;

CheckMesh check_mesh(const std::vector<Eigen::Vector3d>& v, const std::vector<std::array<int, 3>>& faces) {
  CheckMesh m;
  std::vector<CheckMesh::Vertex_index> h;
  h.reserve(v.size());
  for (const auto& p : v) h.push_back(m.add_vertex(CheckKernel::Point_3(p.x(), p.y(), p.z())));
  for (const auto& f : faces) m.add_face(h[f[0]], h[f[1]], h[f[2]]);
  return m;
}

template <typename FaceRange>
void crossing_pairs_of(const FaceRange& range, const CheckMesh& m, std::vector<std::array<int, 2>>* out) {
  std::vector<std::pair<CheckMesh::Face_index, CheckMesh::Face_index>> pairs;
  CGAL::Polygon_mesh_processing::self_intersections(range, m, std::back_inserter(pairs));
  out->reserve(out->size() + pairs.size());
  for (const auto& [f, g] : pairs) out->push_back({static_cast<int>(f.idx()), static_cast<int>(g.idx())});
}
}  // namespace

std::vector<std::array<int, 2>> crossing_face_pairs(const std::vector<Eigen::Vector3d>& v,
                                                    const std::vector<std::array<int, 3>>& faces) {
  const CheckMesh m = check_mesh(v, faces);
  std::vector<std::array<int, 2>> out;
  crossing_pairs_of(CGAL::faces(m), m, &out);
  return out;
}

struct CrossingFaces::Impl {
  CheckMesh mesh;
  std::vector<std::array<int, 3>> faces;
  std::vector<std::vector<int>> faces_at;  ///< per vertex, the faces around it
};

CrossingFaces::CrossingFaces(const std::vector<Eigen::Vector3d>& v, const std::vector<std::array<int, 3>>& faces)
    : impl_(std::make_unique<Impl>()) {
  impl_->mesh = check_mesh(v, faces);
  impl_->faces = faces;
  impl_->faces_at.resize(v.size());
  for (size_t f = 0; f < faces.size(); ++f)
    for (int c : faces[f]) impl_->faces_at[c].push_back(static_cast<int>(f));
  crossing_pairs_of(CGAL::faces(impl_->mesh), impl_->mesh, &pairs_);
}

CrossingFaces::~CrossingFaces() = default;

const std::vector<std::array<int, 2>>& CrossingFaces::move(const std::vector<Eigen::Vector3d>& v, const std::vector<int>& moved) {
  Impl& I = *impl_;
  std::vector<char> dirty(I.faces.size(), 0);
  for (int i : moved) {
    I.mesh.point(CheckMesh::Vertex_index(static_cast<CheckMesh::size_type>(i))) = CheckKernel::Point_3(v[i].x(), v[i].y(), v[i].z());
    for (int f : I.faces_at[i]) dirty[f] = 1;
  }
  // The faces to test again: the moved ones and every face whose box meets one of theirs (CGAL's
  // test pairs only faces whose boxes meet, so no other pair can have changed).
  using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, int, CGAL::Box_intersection_d::ID_EXPLICIT>;
  const auto box_of = [&](int f) {
    const auto& t = I.faces[f];
    CGAL::Bbox_3 b;
    for (int c : t) b += I.mesh.point(CheckMesh::Vertex_index(static_cast<CheckMesh::size_type>(c))).bbox();
    return Box(b, f);
  };
  std::vector<Box> near, all;
  all.reserve(I.faces.size());
  for (size_t f = 0; f < I.faces.size(); ++f) {
    all.push_back(box_of(static_cast<int>(f)));
    if (dirty[f]) near.push_back(all.back());
  }
  std::vector<char> retest = dirty;
  CGAL::box_intersection_d(near.begin(), near.end(), all.begin(), all.end(),
                           [&](const Box& a, const Box& b) { retest[a.info()] = retest[b.info()] = 1; }, std::ptrdiff_t(10),
                           CGAL::Box_intersection_d::CLOSED, CGAL::Box_intersection_d::BIPARTITE);
  std::vector<CheckMesh::Face_index> range;
  for (size_t f = 0; f < retest.size(); ++f)
    if (retest[f]) range.push_back(CheckMesh::Face_index(static_cast<CheckMesh::size_type>(f)));
  std::vector<std::array<int, 2>> kept;
  for (const auto& p : pairs_)
    if (!(retest[p[0]] && retest[p[1]])) kept.push_back(p);
  crossing_pairs_of(range, I.mesh, &kept);
  pairs_ = std::move(kept);
  return pairs_;
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
