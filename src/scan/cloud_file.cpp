#include "scan/cloud_file.hpp"

#include <pcl/PCLPointCloud2.h>

#include <algorithm>
#include <sstream>
#include <optional>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/paths.hpp"
#include "core/random.hpp"
#include "core/json_util.hpp"
#include "mesh/mesh.hpp"
#include "scan/cloud.hpp"
#include "scan/pcl_module.hpp"

namespace handskin {

std::optional<LengthUnit> parse_length_unit(const std::string& n) {
  if (n == "mm") return LengthUnit::Millimetre;
  if (n == "cm") return LengthUnit::Centimetre;
  if (n == "m") return LengthUnit::Metre;
  if (n == "in") return LengthUnit::Inch;
  return std::nullopt;
}

const char* length_unit_name(LengthUnit u) {
  switch (u) {
    case LengthUnit::Centimetre: return "cm";
    case LengthUnit::Metre: return "m";
    case LengthUnit::Inch: return "in";
    default: return "mm";
  }
}

double millimetres_per(LengthUnit u) {
  switch (u) {
    case LengthUnit::Centimetre: return 10.0;
    case LengthUnit::Metre: return 1000.0;
    case LengthUnit::Inch: return 25.4;
    default: return 1.0;
  }
}

const char* point_cloud_extensions() { return ".ply, .pcd, .obj, .stl, .off, .xyz, .pts, .txt"; }

namespace {

/// The extension without its dot ("ply"), lower case.
std::string extension_word(const std::string& path) {
  const std::string e = lower_extension(path);
  return e.empty() ? e : e.substr(1);
}

const pcl::PCLPointField* field_of(const pcl::PCLPointCloud2& c, const std::string& name) {
  for (const auto& f : c.fields)
    if (f.name == name) return &f;
  return nullptr;
}

// One field of every point as doubles, whatever its stored type. pcl::fromPCLPointCloud2 maps
// a field only when its type is the point type's (float): a PLY of doubles — Open3D's and
// CloudCompare's default — read as zeros.
std::vector<double> field_values(const pcl::PCLPointCloud2& c, const pcl::PCLPointField& f, const std::string& path) {
  const size_t n = static_cast<size_t>(c.width) * c.height;
  std::vector<double> v(n);
  const auto at = [&](size_t k) { return c.data.data() + k * c.point_step + f.offset; };
  const auto read = [&](auto zero) {
    using T = decltype(zero);
    for (size_t k = 0; k < n; ++k) {
      T x;
      std::memcpy(&x, at(k), sizeof x);
      v[k] = static_cast<double>(x);
    }
  };
  if (c.data.size() < n * c.point_step || f.offset >= c.point_step)
    throw InputError(path, "field '" + f.name + "' lies outside the points' data");
  switch (f.datatype) {
    case pcl::PCLPointField::INT8: read(std::int8_t{}); break;
    case pcl::PCLPointField::UINT8: read(std::uint8_t{}); break;
    case pcl::PCLPointField::INT16: read(std::int16_t{}); break;
    case pcl::PCLPointField::UINT16: read(std::uint16_t{}); break;
    case pcl::PCLPointField::INT32: read(std::int32_t{}); break;
    case pcl::PCLPointField::UINT32: read(std::uint32_t{}); break;
    case pcl::PCLPointField::FLOAT32: read(float{}); break;
    case pcl::PCLPointField::FLOAT64: read(double{}); break;
    default: throw InputError(path, "field '" + f.name + "' has a type that is not a number");
  }
  return v;
}

// What a PLY's or PCD's header declares, checked against the file before PCL reads it: PCL's
// readers size their buffers by the header's counts, so a header that claims 2 000 000 000
// points over a few bytes (a file cut short, a count mistyped) had `run --cloud` take 23 GB and
// be killed. The points declared must be at most `max_points`, and the body must be long
// enough to hold them: each binary element's fixed size (a list its count's bytes at least),
// two bytes a value in ASCII ("1 "). A compressed PCD's body is not bounded so; its count is.
void check_declared_size(const std::string& path, const std::string& format, size_t max_points) {
  std::ifstream in(path, std::ios::binary);
  std::error_code ec;
  const auto file_size = static_cast<double>(std::filesystem::file_size(path, ec));
  if (ec) return;  // PCL's reader says what is wrong
  const auto scalar_bytes = [](const std::string& t) -> int {
    if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
    if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
    if (t == "int" || t == "uint" || t == "float" || t == "int32" || t == "uint32" || t == "float32") return 4;
    if (t == "double" || t == "float64") return 8;
    return 0;
  };
  std::string line;
  double header = 0, body_min = 0, points = -1;
  bool ascii = false, compressed = false;
  if (format == "ply") {
    double count = 0, element_min = 0;  // the element being declared
    const auto close_element = [&] { body_min += count * element_min; };
    for (int k = 0; k < 10000 && std::getline(in, line); ++k) {
      header += static_cast<double>(line.size()) + 1;
      std::istringstream w(line);
      std::string word, type;
      w >> word;
      if (word == "format") {
        w >> type;
        ascii = type == "ascii";
      } else if (word == "element") {
        close_element();
        std::string name;
        w >> name >> count;
        if (!w || count < 0) return;  // PCL's reader says what is wrong
        element_min = 0;
        if (name == "vertex") points = count;
      } else if (word == "property") {
        w >> type;
        if (type == "list") {
          std::string count_type;
          w >> count_type;
          element_min += ascii ? 2 : scalar_bytes(count_type);
        } else {
          element_min += ascii ? 2 : scalar_bytes(type);
        }
      } else if (word == "end_header") {
        close_element();
        break;
      }
    }
  } else {  // pcd
    double per_point = 0, width = 0, height = 1;
    std::vector<double> sizes, counts;
    for (int k = 0; k < 100 && std::getline(in, line); ++k) {
      header += static_cast<double>(line.size()) + 1;
      std::istringstream w(line);
      std::string word;
      w >> word;
      double v;
      if (word == "SIZE") {
        while (w >> v) sizes.push_back(v);
      } else if (word == "COUNT") {
        while (w >> v) counts.push_back(v);
      } else if (word == "WIDTH") {
        w >> width;
      } else if (word == "HEIGHT") {
        w >> height;
      } else if (word == "POINTS") {
        w >> points;
      } else if (word == "DATA") {
        std::string kind;
        w >> kind;
        ascii = kind == "ascii";
        compressed = kind == "binary_compressed";
        break;
      }
    }
    if (points < 0) points = width * height;
    for (size_t f = 0; f < sizes.size(); ++f) {
      const double c = f < counts.size() ? counts[f] : 1;
      per_point += ascii ? 2 * c : sizes[f] * c;
    }
    if (!compressed) body_min = points * per_point;
  }
  if (ascii) body_min = std::max(0.0, body_min - 1);  // the last value's line may end the file without a newline
  const auto whole = [](double v) { return std::to_string(static_cast<long long>(std::min(std::max(v, 0.0), 9e18))); };
  if (points > static_cast<double>(max_points))
    throw InputError(path, "its header declares " + whole(points) + " points, more than " + std::to_string(max_points));
  if (body_min > file_size - header)
    throw InputError(path, "its header declares " + whole(points) + " points and what else it holds in at least " +
                               whole(body_min) + " bytes, but " + whole(file_size - header) +
                               " bytes follow it: the file is cut short, or its header's counts are wrong");
}

// PLY and PCD through PCL's readers (binary and ASCII; a PLY mesh's faces are skipped), in
// handskin's PCL module (pcl_module.hpp).
void read_pcl(PointCloudFile* out) {
  const PclModule& m = pcl_module(out->path);
  pcl::PCLPointCloud2 blob;
  std::string error;
  if (m.read(out->path.c_str(), out->format == "pcd" ? 1 : 0, &blob, &error) != 0)
    throw InputError(out->path, "unreadable " + out->format + " file" + (error.empty() ? "" : ": " + error));
  const pcl::PCLPointField *fx = field_of(blob, "x"), *fy = field_of(blob, "y"), *fz = field_of(blob, "z");
  if (!fx || !fy || !fz) throw InputError(out->path, "no x, y, z fields: not a point cloud");
  const std::vector<double> x = field_values(blob, *fx, out->path), y = field_values(blob, *fy, out->path),
                            z = field_values(blob, *fz, out->path);
  const pcl::PCLPointField *fnx = field_of(blob, "normal_x"), *fny = field_of(blob, "normal_y"),
                           *fnz = field_of(blob, "normal_z"), *fl = field_of(blob, "label");
  const bool normals = fnx && fny && fnz, labels = fl;
  std::vector<double> nx, ny, nz, label;
  if (normals)
    nx = field_values(blob, *fnx, out->path), ny = field_values(blob, *fny, out->path), nz = field_values(blob, *fnz, out->path);
  if (labels) label = field_values(blob, *fl, out->path);
  const bool organised = blob.height > 1;
  out->points.reserve(x.size());
  for (size_t k = 0; k < x.size(); ++k) {
    const Eigen::Vector3d p(x[k], y[k], z[k]);
    if (!p.allFinite()) {
      // An organised cloud's NaN points are its no-returns; anywhere else a bad coordinate.
      if (organised && p.array().isNaN().all()) {
        ++out->no_return;
        continue;
      }
      throw InputError(out->path, "point " + std::to_string(k) + " has a non-finite coordinate");
    }
    out->points.push_back(p);
    if (normals) out->normals.emplace_back(nx[k], ny[k], nz[k]);
    if (labels) {
      if (!(label[k] >= 0 && label[k] <= 4294967295.0 && label[k] == std::floor(label[k])))
        throw InputError(out->path, "point " + std::to_string(k) + " has label " + number_text(label[k]) +
                                        ": not a whole number");
      out->labels.push_back(static_cast<std::uint32_t>(label[k]));
    }
  }
}

// OBJ, STL (ASCII or binary) and OFF through OpenMesh's readers: the vertices (an STL's
// corners merged), whatever the faces.
void read_openmesh(PointCloudFile* out) {
  std::optional<Mesh> mesh;
  try {
    mesh = read_mesh_file(out->path);
  } catch (const std::exception& e) {
    throw InputError(out->path, std::string("unreadable ") + out->format + " file: " + e.what());
  }
  if (!mesh) throw InputError(out->path, "unreadable " + out->format + " file");
  out->points.reserve(mesh->vertices.size());
  for (size_t k = 0; k < mesh->vertices.size(); ++k) {
    const Eigen::Vector3d& p = mesh->vertices[k];
    if (!p.allFinite()) throw InputError(out->path, "vertex " + std::to_string(k) + " has a non-finite coordinate");
    out->points.push_back(p);
  }
  out->faces = mesh->faces;
}

// A PLY's faces, when its header declares some: read by OpenMesh (PCL's cloud reader skips
// them), kept when its vertices are PCL's one for one (else the file is taken as a cloud).
void read_ply_faces(PointCloudFile* out) {
  std::ifstream in(out->path, std::ios::binary);
  std::string line;
  bool faces = false;
  for (int k = 0; k < 200 && std::getline(in, line) && line.rfind("end_header", 0) != 0; ++k) {
    std::istringstream words(line);
    std::string a, b;
    long n = 0;
    if (words >> a >> b >> n && a == "element" && b == "face" && n > 0) faces = true;
  }
  if (!faces) return;
  try {
    const std::optional<Mesh> mesh = read_mesh_file(out->path);
    if (mesh && mesh->vertices.size() == out->points.size()) out->faces = mesh->faces;
  } catch (const std::exception&) {  // the vertices stand as a cloud
  }
}

// XYZ / PTS / TXT: one point per line, "x y z" (spaces, tabs or commas), more columns
// ignored except an .xyz's "x y z nx ny nz" when every row's last three are unit vectors. A
// .pts's first line may be its point count; '#' and '//' lines are comments. Written here:
// no Debian library reads these loose text formats with line-numbered errors.
void read_text(PointCloudFile* out, size_t max_points) {
  std::ifstream in(out->path);
  if (!in) throw InputError(out->path, "cannot be read");
  std::string line;
  size_t line_no = 0;
  std::vector<Eigen::Vector3d> second;
  bool unit_vectors = out->format == "xyz", first_data = true;
  while (std::getline(in, line)) {
    ++line_no;
    for (char& c : line)
      if (c == ',' || c == ';' || c == '\t' || c == '\r') c = ' ';
    const size_t s = line.find_first_not_of(' ');
    if (s == std::string::npos || line[s] == '#' || line.compare(s, 2, "//") == 0) continue;
    std::vector<double> v;
    const char* p = line.c_str();
    while (true) {
      while (*p == ' ') ++p;
      if (!*p) break;
      char* end = nullptr;
      errno = 0;
      const double x = std::strtod(p, &end);
      if (end == p || errno == ERANGE || (*end && *end != ' '))
        throw InputError(out->path, "line " + std::to_string(line_no) + ": not a number: '" +
                                        std::string(p, std::min<size_t>(std::strlen(p), 20)) + "'");
      v.push_back(x);
      p = end;
    }
    const bool count_line = first_data && v.size() == 1;
    first_data = false;
    if (count_line) continue;
    if (v.size() < 3)
      throw InputError(out->path, "line " + std::to_string(line_no) + ": " + std::to_string(v.size()) +
                                      " numbers; a point needs x y z");
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(v[k]))
        throw InputError(out->path, "line " + std::to_string(line_no) + ": a non-finite coordinate");
    if (out->points.size() >= max_points)
      throw InputError(out->path, "more than " + std::to_string(max_points) + " points");
    out->points.emplace_back(v[0], v[1], v[2]);
    if (unit_vectors && v.size() == 6) {
      const Eigen::Vector3d n(v[3], v[4], v[5]);
      if (std::abs(n.norm() - 1.0) < 0.02) second.push_back(n);
      else unit_vectors = false;
    } else {
      unit_vectors = false;
    }
  }
  if (unit_vectors && second.size() == out->points.size()) out->normals = std::move(second);
}

}  // namespace

PointCloudFile read_point_cloud(const std::string& path, LengthUnit unit, size_t max_points) {
  PointCloudFile out;
  out.path = path;
  out.format = extension_word(path);
  const std::string& f = out.format;
  const bool pcl_format = f == "ply" || f == "pcd", mesh_format = f == "obj" || f == "stl" || f == "off",
             text_format = f == "xyz" || f == "pts" || f == "txt";
  if (!pcl_format && !mesh_format && !text_format)
    throw InputError(path, "unknown point-cloud extension (use one of " + std::string(point_cloud_extensions()) + ")");
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw InputError(path, "no such file");
  silence_pcl_console();
  if (pcl_format) {
    check_declared_size(path, f, max_points);
    read_pcl(&out);
    if (f == "ply") read_ply_faces(&out);
  }
  else if (mesh_format) read_openmesh(&out);
  else read_text(&out, max_points);
  if (out.points.empty()) throw InputError(path, "holds no points");
  if (out.points.size() > max_points)
    throw InputError(path, "holds " + std::to_string(out.points.size()) + " points, more than " +
                               std::to_string(max_points));
  const double s = millimetres_per(unit);
  if (s != 1.0)
    for (auto& p : out.points) p *= s;
  return out;
}

size_t sample_sparse_mesh(PointCloudFile* file, double spacing_mm) {
  PointCloudFile& f = *file;
  if (f.faces.empty() || !(spacing_mm > 0)) return 0;
  double edges = 0, area = 0;
  std::vector<double> cumulative;
  cumulative.reserve(f.faces.size());
  const auto valid = [&](const std::array<int, 3>& t) {
    for (int c : t)
      if (c < 0 || static_cast<size_t>(c) >= f.points.size()) return false;
    return true;
  };
  for (const auto& t : f.faces) {
    if (valid(t)) {
      const Eigen::Vector3d &a = f.points[t[0]], &b = f.points[t[1]], &c = f.points[t[2]];
      edges += (b - a).norm() + (c - b).norm() + (a - c).norm();
      area += 0.5 * (b - a).cross(c - a).norm();
    }
    cumulative.push_back(area);
  }
  const double mean_edge = edges / (3.0 * static_cast<double>(f.faces.size()));
  if (!(mean_edge > 1.4 * spacing_mm) || !(area > 0)) return 0;  // as dense as a scanner's points already
  const size_t n = static_cast<size_t>(std::llround(std::min(2.0e6, area / (spacing_mm * spacing_mm))));
  const bool normals = f.normals.size() == f.points.size();
  Rng rng(1);  // the same samples for the same file
  std::vector<Eigen::Vector3d> points, sample_normals;
  points.reserve(n);
  if (normals) sample_normals.reserve(n);
  for (size_t k = 0; k < n; ++k) {
    const double at = rng.uniform() * area;
    const size_t t = static_cast<size_t>(std::upper_bound(cumulative.begin(), cumulative.end(), at) - cumulative.begin());
    const auto& tri = f.faces[std::min(t, f.faces.size() - 1)];
    if (!valid(tri)) continue;
    const double r1 = std::sqrt(rng.uniform()), r2 = rng.uniform();
    const double wa = 1 - r1, wb = r1 * (1 - r2), wc = r1 * r2;
    points.push_back(wa * f.points[tri[0]] + wb * f.points[tri[1]] + wc * f.points[tri[2]]);
    if (normals) {
      const Eigen::Vector3d m = wa * f.normals[tri[0]] + wb * f.normals[tri[1]] + wc * f.normals[tri[2]];
      sample_normals.push_back(m.norm() > 1e-12 ? Eigen::Vector3d(m.normalized()) : Eigen::Vector3d::Zero());
    }
  }
  // The samples stand for the surface: the vertices lie where the mesher put them (dense at
  // the curves, sparse on the flats), which no scanner does (kept beside the samples, they
  // made the ring finger's tube fold on a mesher's hand).
  f.points = std::move(points);
  f.normals = std::move(sample_normals);
  f.faces.clear();
  return f.points.size();
}

void make_normals_unit(PointCloudFile* file) {
  for (auto& n : file->normals) {
    const double len = n.norm();
    n = len > 1e-12 && std::isfinite(len) ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
  }
}

}  // namespace handskin
