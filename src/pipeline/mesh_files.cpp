#include "pipeline/mesh_files.hpp"

#include <array>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/paths.hpp"
#include "patches/patches.hpp"
#include "rigging/gltf.hpp"

namespace handskin {

namespace {

/// The free-form surfaces of an OBJ (`cstype bezier`, `deg 3 3`, `surf u0 u1 v0 v1` and 16
/// control-point indices, as patches.obj writes them) tessellated; nullopt when the file has
/// no `surf`. Our own reader: OpenMesh's OBJ reader skips free-form geometry.
std::optional<Mesh> read_obj_patches(const std::string& path) {
  const std::string text = read_file(path);
  if (text.find("\nsurf ") == std::string::npos) return std::nullopt;
  std::vector<Eigen::Vector3d> v;
  std::vector<std::array<int, 16>> surfs;
  std::istringstream in(text);
  std::string line;
  long number = 0;
  bool bicubic = true;
  while (std::getline(in, line)) {
    ++number;
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    const std::string where = "line " + std::to_string(number);
    if (key == "v") {
      Eigen::Vector3d p;
      if (!(ls >> p.x() >> p.y() >> p.z()) || !p.allFinite()) throw InputError(path, where + ": a vertex needs three finite numbers");
      v.push_back(p);
    } else if (key == "deg") {
      int a = 0, b = 0;
      ls >> a >> b;
      bicubic = a == 3 && b == 3;
    } else if (key == "surf") {
      if (!bicubic) throw InputError(path, where + ": only bicubic surfaces (deg 3 3) are read");
      double range[4];
      for (double& r : range) ls >> r;
      std::array<int, 16> c{};
      for (int& k : c) {
        std::string tok;
        if (!(ls >> tok)) throw InputError(path, where + ": a bicubic surface needs 16 control points");
        try {
          k = std::stoi(tok.substr(0, tok.find('/')));
        } catch (const std::exception&) {
          throw InputError(path, where + ": '" + tok + "' is not a vertex index");
        }
        k = k < 0 ? static_cast<int>(v.size()) + k : k - 1;  // OBJ: 1-based, negative from the end
        if (k < 0 || k >= static_cast<int>(v.size())) throw InputError(path, where + ": vertex index out of range");
      }
      surfs.push_back(c);
    }
  }
  if (surfs.empty()) throw InputError(path, "no bicubic surface");
  Mesh m;
  const int n = kPatchGrid;
  for (const auto& c : surfs) {
    BezierPatch p;
    for (int k = 0; k < 16; ++k) p.P[k] = v[c[k]];
    const int base = static_cast<int>(m.vertices.size());
    for (int i = 0; i <= n; ++i)
      for (int j = 0; j <= n; ++j) m.vertices.push_back(p.eval(static_cast<double>(i) / n, static_cast<double>(j) / n));
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        const int a = base + i * (n + 1) + j, b = a + 1, d = a + (n + 1), e = d + 1;
        m.faces.push_back({a, d, e});
        m.faces.push_back({a, e, b});
      }
  }
  // The patches' parameter directions need not make the faces face out: a closed net is
  // turned outward by its signed volume.
  double volume = 0;
  for (const auto& f : m.faces) volume += m.vertices[f[0]].dot(m.vertices[f[1]].cross(m.vertices[f[2]])) / 6.0;
  if (volume < 0)
    for (auto& f : m.faces) std::swap(f[1], f[2]);
  return m;
}

}  // namespace

Mesh read_any_mesh(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".glb") return read_skin_glb(path).mesh;
  if (ext == ".obj")
    if (std::optional<Mesh> patches = read_obj_patches(path)) return *patches;
  return load_mesh(path);
}

void require_mesh_extension(const std::string& path, const std::string& flag) {
  const std::string ext = lower_extension(path);
  if (ext != ".ply" && ext != ".obj" && ext != ".off" && ext != ".stl")
    throw UsageError(flag, "'" + path + "': a mesh is written as .ply, .obj, .off or .stl (by its extension)");
}

}  // namespace handskin
