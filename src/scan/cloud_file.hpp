#pragma once
/// Point clouds from any scanner (issue 37): one reader for the files today's scanners and
/// their software write — PLY (binary or ASCII; points, or a mesh's vertices), PCD, OBJ, STL,
/// OFF, and XYZ/PTS/TXT text — into plain arrays in millimetres.
#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <array>
#include <string>
#include <vector>

namespace handskin {

/// The length unit a cloud file's coordinates are in (`run --units`).
enum class LengthUnit { Millimetre, Centimetre, Metre, Inch };
/// "mm", "cm", "m", "in" → the unit; nullopt for anything else.
std::optional<LengthUnit> parse_length_unit(const std::string& name);
const char* length_unit_name(LengthUnit u);
double millimetres_per(LengthUnit u);

/// A cloud file read: points (mm), normals when the file has them (else empty; as stored,
/// not made unit), labels when a PLY/PCD has a `label` field (else empty: handskin's
/// merged.ply keeps each point's side there), and what it was.
struct PointCloudFile {
  std::string path;
  std::string format;  ///< "ply", "pcd", "obj", "stl", "off", "xyz", "pts", "txt"
  std::vector<Eigen::Vector3d> points, normals;
  std::vector<std::uint32_t> labels;
  size_t no_return = 0;  ///< an organised cloud's NaN points (no return), dropped
  /// A mesh's triangles (OBJ, STL, OFF, a PLY with faces), indices into `points`; empty for a cloud.
  std::vector<std::array<int, 3>> faces;
};

/// A mesh given as a cloud (`faces` not empty) whose vertices lie sparser than a scanner's
/// points (mean edge over 0.7 mm): its surface sampled, area-uniform, at one point per
/// `spacing_mm`² (fixed seed; at most 2 000 000 points), the samples in place of its vertices
/// (with normals interpolated from the vertices' when it has them; `faces` emptied). The points
/// in mm. A decimated or coarsely meshed hand (a mesher's 1.6 mm facets: ~22 000 vertices)
/// left the skeleton's placement without its digits. Returns the samples' count (0: the mesh
/// is dense enough, or not a mesh, and is left as it is).
size_t sample_sparse_mesh(PointCloudFile* file, double spacing_mm = 0.5);
/// Each normal made unit length; one of zero or non-finite length becomes (0, 0, 0), "none".
void make_normals_unit(PointCloudFile* file);

/// The extensions read_point_cloud knows, for messages: ".ply, .pcd, .obj, .stl, .off, .xyz, .pts, .txt".
const char* point_cloud_extensions();

/// Read a cloud file and scale it to mm: the project's one reader of point clouds (`run
/// --cloud`, `convert`, merged.ply). Throws InputError naming the file (and the line, point or
/// key) when it cannot be read, has an unknown extension, holds no points, holds a
/// non-finite coordinate (an organised PLY's or PCD's NaN points are no-returns and are
/// dropped), or holds more than `max_points` points. Normals are kept as stored, non-finite
/// ones too (make_normals_unit makes them "none").
PointCloudFile read_point_cloud(const std::string& path, LengthUnit unit = LengthUnit::Millimetre,
                                size_t max_points = 20'000'000);

}  // namespace handskin
