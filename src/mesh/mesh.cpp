#include "mesh/mesh.hpp"

#include "mesh/trimesh.hpp"

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/System/omstream.hh>

#include <Eigen/Geometry>  // cross(): only declared by <Eigen/Core>
#include <cmath>
#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <optional>
#include <vector>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/paths.hpp"

namespace handskin {

namespace {

/// The fewest bytes one value of a PLY property type takes in a binary file.
size_t ply_type_bytes(const std::string& t) {
  if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
  if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
  if (t == "double" || t == "float64") return 8;
  return 4;  // int, uint, float, int32, uint32, float32 (and anything else: the reader refuses it)
}

/// A header's declared element counts against the file's size: OpenMesh's readers reserve
/// what the header declares before reading, so a header declaring 10^11 vertices made them
/// fill memory for minutes (found by the Python module's bad-input test). PLY (each element at
/// least its properties' bytes, 2 per value in ASCII), OFF (ASCII: 6 bytes a vertex, 8 a face)
/// and binary STL (50 bytes a triangle) are checked; a file that cannot hold what it declares
/// is an InputError naming the count.
void check_declared_counts(const std::string& path) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) return;  // the reader says what is wrong
  const std::string ext = lower_extension(path);
  std::ifstream in(path, std::ios::binary);
  auto refuse = [&](const std::string& what, double count, double bytes) {
    if (count * bytes > static_cast<double>(size))
      throw InputError(path, "its header declares " + std::to_string(static_cast<long long>(count)) + " " + what +
                                 ", more than its " + std::to_string(size) + " bytes can hold");
  };
  if (ext == ".ply") {
    std::string line, format;
    std::vector<std::pair<std::string, double>> elements;  // name, count
    std::vector<size_t> bytes;                              // per element: fewest bytes (binary)
    std::vector<size_t> values;                             // per element: values (ASCII)
    for (int n = 0; n < 10000 && std::getline(in, line); ++n) {
      std::istringstream ls(line);
      std::string key;
      ls >> key;
      if (key == "end_header") break;
      if (key == "format") ls >> format;
      if (key == "element") {
        std::string name;
        double count = 0;
        ls >> name >> count;
        elements.emplace_back(name, count);
        bytes.push_back(0);
        values.push_back(0);
      }
      if (key == "property" && !elements.empty()) {
        std::string type;
        ls >> type;
        if (type == "list") {
          std::string count_type;
          ls >> count_type;
          bytes.back() += ply_type_bytes(count_type);  // an empty list: its count alone
        } else {
          bytes.back() += ply_type_bytes(type);
        }
        values.back() += 1;
      }
    }
    double total = 0;
    for (size_t i = 0; i < elements.size(); ++i) {
      // (at least 1 byte: an element without properties is still a line, and nothing a reader takes)
      const double each = std::max(1.0, format == "ascii" ? 2.0 * static_cast<double>(values[i]) : static_cast<double>(bytes[i]));
      refuse("'" + elements[i].first + "' elements", elements[i].second, each);
      total += elements[i].second * each;
    }
    refuse("elements in all", 1, total);
  } else if (ext == ".off") {
    std::string magic;
    double v = 0, f = 0;
    in >> magic >> v >> f;
    if (in && magic.find("OFF") != std::string::npos && magic.find("BINARY") == std::string::npos) {
      refuse("vertices", v, 6);
      refuse("faces", f, 8);
    }
  } else if (ext == ".stl") {
    char head[84] = {0};
    in.read(head, 84);
    if (in.gcount() == 84 && std::string(head, 5) != "solid") {
      std::uint32_t n = 0;
      std::memcpy(&n, head + 80, 4);
      refuse("triangles", n, 50);
    }
  }
}

}  // namespace

std::optional<Mesh> read_mesh_file(const std::string& path) {
  check_declared_counts(path);
  TriMesh mesh;
  OpenMesh::IO::Options opt;
  try {
    if (!OpenMesh::IO::read_mesh(mesh, path, opt)) return std::nullopt;
  } catch (const std::bad_alloc&) {  // a header that declares more elements than memory holds
    throw InputError(path, "unreadable mesh: its header declares more elements than fit in memory");
  }
  return from_trimesh(mesh);
}

Mesh load_mesh(const std::string& path) {
  read_file(path);  // existence and readability, with a clear message
  std::optional<Mesh> mesh = read_mesh_file(path);
  if (!mesh) throw InputError(path, "unreadable mesh");
  if (mesh->faces.empty()) throw InputError(path, "mesh has no faces");
  for (const Eigen::Vector3d& p : mesh->vertices)
    if (!p.allFinite()) throw InputError(path, "mesh holds non-finite coordinates");
  return *mesh;
}

void save_mesh(const std::string& path, const Mesh& m) {
  omlog().disable();  // the OBJ writer logs "write file" to stderr on every call
  const TriMesh mesh = to_trimesh(m);
  write_via_temp(path, [&](const std::string& tmp) {
    OpenMesh::IO::Options opt = OpenMesh::IO::Options::Binary;
    const std::string ext = std::filesystem::path(path).extension().string();
    if (ext == ".obj" || ext == ".off") opt = OpenMesh::IO::Options::Default;
    if (!OpenMesh::IO::write_mesh(mesh, tmp, opt, 10)) throw InputError(path, "cannot write mesh");
  });
}

std::string obj_text(const Mesh& mesh, const std::vector<std::array<Eigen::Vector2f, 3>>* corner_uv,
                     const std::string& mtllib) {
  HS_CHECK(!corner_uv || corner_uv->size() == mesh.faces.size(), "one texture corner triple per face");
  std::string t;
  t.reserve(mesh.vertices.size() * 80 + mesh.faces.size() * 40);
  char buf[128];
  t += "# handskin: " + std::to_string(mesh.vertices.size()) + " vertices, " + std::to_string(mesh.faces.size()) +
       " faces; mm\n";
  if (!mtllib.empty()) t += "mtllib " + mtllib + "\n";
  for (const auto& v : mesh.vertices) {
    std::snprintf(buf, sizeof buf, "v %.6f %.6f %.6f\n", v.x(), v.y(), v.z());
    t += buf;
  }
  for (const auto& n : vertex_normals(mesh.vertices, mesh.faces)) {
    std::snprintf(buf, sizeof buf, "vn %.6f %.6f %.6f\n", n.x(), n.y(), n.z());
    t += buf;
  }
  // One vt per distinct corner value, in order of first use.
  std::vector<std::array<int, 3>> vt_of(mesh.faces.size());
  if (corner_uv) {
    std::map<std::pair<float, float>, int> index;
    for (size_t f = 0; f < mesh.faces.size(); ++f)
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector2f& uv = (*corner_uv)[f][k];
        const auto [it, added] = index.try_emplace({uv.x(), uv.y()}, static_cast<int>(index.size()) + 1);
        if (added) {
          std::snprintf(buf, sizeof buf, "vt %.7g %.7g\n", uv.x(), 1.0 - uv.y());
          t += buf;
        }
        vt_of[f][k] = it->second;
      }
  }
  if (!mtllib.empty()) t += "usemtl skin\n";
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const auto& F = mesh.faces[f];
    if (corner_uv)
      std::snprintf(buf, sizeof buf, "f %d/%d/%d %d/%d/%d %d/%d/%d\n", F[0] + 1, vt_of[f][0], F[0] + 1, F[1] + 1,
                    vt_of[f][1], F[1] + 1, F[2] + 1, vt_of[f][2], F[2] + 1);
    else
      std::snprintf(buf, sizeof buf, "f %d//%d %d//%d %d//%d\n", F[0] + 1, F[0] + 1, F[1] + 1, F[1] + 1, F[2] + 1,
                    F[2] + 1);
    t += buf;
  }
  return t;
}

Mesh manifold_faces(const Mesh& mesh, size_t* dropped) {
  size_t n = 0;
  Mesh kept = from_trimesh(to_trimesh(mesh, &n));
  if (dropped) *dropped = n;
  return kept;
}

Mesh from_trimesh(const TriMesh& mesh) {
  Mesh m;
  m.vertices.reserve(mesh.n_vertices());
  for (auto vh : mesh.vertices()) {
    const auto& p = mesh.point(vh);
    m.vertices.emplace_back(p[0], p[1], p[2]);
  }
  m.faces.reserve(mesh.n_faces());
  for (auto fh : mesh.faces()) {
    std::array<int, 3> t{};
    int k = 0;
    for (auto vh : mesh.fv_range(fh)) t[k++] = vh.idx();
    m.faces.push_back(t);
  }
  return m;
}

TriMesh to_trimesh(const Mesh& mesh, size_t* dropped) {
  TriMesh m;
  std::vector<TriMesh::VertexHandle> h;
  h.reserve(mesh.vertices.size());
  for (const auto& p : mesh.vertices) h.push_back(m.add_vertex(TriMesh::Point(p.x(), p.y(), p.z())));
  size_t n = 0;
  for (const auto& f : mesh.faces)
    if (!m.add_face(h[f[0]], h[f[1]], h[f[2]]).is_valid()) ++n;
  if (dropped) *dropped = n;
  return m;
}

MeshHealth mesh_health(const Mesh& mesh) { return trimesh_health(to_trimesh(mesh)); }

std::vector<Eigen::Vector3d> shading_normals(const Mesh& m) {
  TriMesh mesh = to_trimesh(m);
  mesh.request_vertex_normals();
  mesh.request_face_normals();
  mesh.update_normals();
  std::vector<Eigen::Vector3d> n;
  n.reserve(mesh.n_vertices());
  for (auto v : mesh.vertices()) {
    const auto& u = mesh.normal(v);
    n.emplace_back(u[0], u[1], u[2]);
  }
  return n;
}

MeshHealth trimesh_health(const TriMesh& mesh) {
  MeshHealth h;
  h.vertices = mesh.n_vertices();
  h.faces = mesh.n_faces();
  for (auto e : mesh.edges())
    if (mesh.is_boundary(e)) ++h.boundary_edges;
  for (auto v : mesh.vertices())
    if (!mesh.is_manifold(v)) ++h.nonmanifold_vertices;
  // Components by flood fill over face adjacency.
  std::vector<int> comp(mesh.n_faces(), -1);
  std::vector<int> stack;
  for (auto f0 : mesh.faces()) {
    if (comp[f0.idx()] >= 0) continue;
    const int c = static_cast<int>(h.components++);
    stack.assign(1, f0.idx());
    comp[f0.idx()] = c;
    while (!stack.empty()) {
      const auto f = mesh.face_handle(stack.back());
      stack.pop_back();
      for (auto g : mesh.ff_range(f))
        if (comp[g.idx()] < 0) {
          comp[g.idx()] = c;
          stack.push_back(g.idx());
        }
    }
  }
  for (auto f : mesh.faces()) {
    auto it = mesh.cfv_iter(f);
    const auto a = mesh.point(*it++), b = mesh.point(*it++), c = mesh.point(*it);
    h.volume_mm3 += OpenMesh::dot(a, OpenMesh::cross(b, c)) / 6.0;
    h.area_mm2 += 0.5 * OpenMesh::cross(b - a, c - a).norm();
  }
  return h;
}

std::vector<Eigen::Vector3d> vertex_normals(const std::vector<Eigen::Vector3d>& v, const std::vector<std::array<int, 3>>& faces) {
  std::vector<Eigen::Vector3d> n(v.size(), Eigen::Vector3d::Zero());
  for (const auto& f : faces) {
    const Eigen::Vector3d a = (v[f[1]] - v[f[0]]).cross(v[f[2]] - v[f[0]]);
    for (int k : f) n[k] += a;
  }
  for (auto& u : n) u = u.norm() > 0 ? u.normalized() : Eigen::Vector3d::UnitZ();
  return n;
}

}  // namespace handskin
