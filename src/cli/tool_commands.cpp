// render, convert: pictures and format conversion.
#include <filesystem>
#include <memory>

#include "cli/commands.hpp"
#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/rig.hpp"
#include "mesh/mesh.hpp"
#include "pipeline/mesh_files.hpp"
#include "posture/skeleton.hpp"
#include "render/preview.hpp"
#include "scan/cloud.hpp"
#include "scan/cubist_io.hpp"

namespace handskin::cli {

namespace {
namespace fs = std::filesystem;

// Pictures are bounded: the rasteriser holds a few buffers of width × height.
constexpr int kMinPictureWidth = 16, kMaxPictureWidth = 4096;

// ---------------- render ----------------
struct RenderArgs {
  std::string mesh, scan, rig, out, view = "back";
  int width = 1024;
  bool width_given = false;  ///< a scan is drawn one column a point unless --size says
  bool force = false;
};

void render(const RenderArgs& a) {
  if (a.mesh.empty() == a.scan.empty()) throw UsageError("render", "give exactly one of --mesh or --scan");
  require_png(a.out, "--out");
  if (!a.scan.empty() && !a.rig.empty()) throw UsageError("--rig", "draws a mesh's joints; a scan is drawn in its own frame");
  const Eigen::Matrix3d view = named_view(a.view);  // a usage error before the output is claimed
  OutputFiles files({a.out}, output_options(a.force));
  if (!a.scan.empty()) {
    write_file_atomic(files.stage(a.out), render_scan_png(load_scan(a.scan), a.width_given ? a.width : 0));
  } else {
    RenderOptions ro;
    ro.width = a.width;
    ro.height = a.width * 3 / 4;
    ro.view = view;
    std::optional<Rig> rig;
    if (!a.rig.empty()) rig = load_rig(a.rig);  // the same checks as solve: a rig one command refuses, all do
    const Mesh mesh = read_any_mesh(a.mesh);
    if (rig) {
      // Views are defined in the hand frame: bring the mesh frame there through the rig.
      ro.view = ro.view * hand_frame_from_rig(*rig).linear();
      for (const auto& j : rig->joints) ro.points.push_back(j);
    }
    write_file_atomic(files.stage(a.out), render_mesh_png({&mesh}, ro));
  }
  files.commit();
  std::printf("%s\n", a.out.c_str());
}

// ---------------- convert ----------------
struct ConvertArgs {
  std::string in, out, like, side;
  bool force = false;
};

// A cloud handskin writes (.ply, .pcd); it reads those and the scanners' text clouds (is_cloud_file).
bool is_cloud_path(const std::string& p) {
  const std::string e = lower_extension(p);
  return e == ".ply" || e == ".pcd";
}

bool is_mesh_path(const std::string& p) {
  const std::string e = lower_extension(p);
  return e == ".obj" || e == ".off" || e == ".stl" || e == ".glb";
}

void convert(const ConvertArgs& a, const Progress& progress) {
  // What is converted, decided once: its usage errors, the files it claims and its work follow.
  enum class Kind { Mesh, ScanToCloud, CloudToCloud, CloudToScan };
  const Kind kind = is_mesh_path(a.in) || is_mesh_path(a.out) ? Kind::Mesh  // any mesh the project writes, to .ply/.obj/.off/.stl
                    : !is_cloud_file(a.in)                   ? Kind::ScanToCloud
                    : is_cloud_path(a.out)                    ? Kind::CloudToCloud
                                                              : Kind::CloudToScan;
  if (kind == Kind::Mesh) require_mesh_extension(a.out, "--out");
  if (kind == Kind::CloudToScan && is_cloud_file(a.out))
    throw UsageError("--out", "'" + a.out + "': a cloud is written as .ply or .pcd (by its extension)");
  // Onto itself: the file read would be replaced by what convert makes of it (a cloud's or a
  // mesh's other format, a scan's cloud), which is not always all it held.
  if (std::error_code ec; fs::exists(a.in, ec) && fs::exists(a.out, ec) && fs::equivalent(a.in, a.out, ec))
    throw UsageError("--out", "'" + a.out + "' is the file --in reads; convert writes a new file");
  // A scan is given by its stem (`back` for back.png and back.json); a file that is there under
  // the name given is none of the kinds convert reads (a STEP file, an FBX…), not a stem.
  if (std::error_code ec; kind == Kind::ScanToCloud && fs::is_regular_file(a.in, ec))
    throw InputError(a.in, "not a file convert reads: a scan (its stem, or its .png or .json), a cloud (.ply, .pcd, .xyz, "
                           ".pts, .txt) or a mesh (.obj, .off, .stl, .glb)");
  if (kind == Kind::ScanToCloud && !is_cloud_path(a.out))
    throw UsageError("--out", "converting a scan needs a .ply or .pcd output");
  if (kind == Kind::CloudToScan) {
    if (!a.side.empty() && a.side != "back" && a.side != "palm") throw UsageError("--side", "'" + a.side + "': must be back or palm");
    if (a.side.empty() && a.like.empty()) throw UsageError("--side", "give --side back or --side palm (or --like <stem>)");
  }
  // The files written: a scan's two (<stem>.png, <stem>.json), else the one named.
  OutputFiles files(kind == Kind::CloudToScan ? std::vector<std::string>{a.out + ".png", a.out + ".json"}
                                              : std::vector<std::string>{a.out},
                    output_options(a.force));
  if (kind == Kind::Mesh) {
    const Mesh mesh = read_any_mesh(a.in);
    save_mesh(files.stage(a.out), mesh);
    progress("convert", std::to_string(mesh.vertices.size()) + " vertices, " + std::to_string(mesh.faces.size()) +
                            " faces written");
  } else if (kind == Kind::ScanToCloud) {
    const RangeScan scan = load_scan(a.in);
    save_cloud(files.stage(a.out), *dense_copy(*scan_to_organized_cloud(scan)));
    progress("convert", std::to_string(scan.count_valid()) + " points written");
  } else if (kind == Kind::CloudToCloud) {
    const PointCloudFile cloud = load_cloud_file(a.in);  // its normals and side labels kept (a merged.ply's)
    save_cloud_file(files.stage(a.out), cloud);
    progress("convert", std::to_string(cloud.points.size()) + " points written" +
                            (cloud.normals.empty() ? "" : cloud.labels.empty() ? ", with their normals" : ", with their normals and labels"));
  } else {
    // The grid comes from an existing scan's sidecar (--like) or the CUBIST defaults.
    ScanMeta meta = a.like.empty() ? ScanMeta{} : parse_scan_meta(read_file(a.like + ".json"), a.like + ".json");
    if (a.side == "back") meta.side = ScanSide::Back;
    else if (a.side == "palm") meta.side = ScanSide::Palm;
    meta.device = "converted from " + fs::path(a.in).filename().string();
    size_t dropped = 0;
    const RangeScan scan = cloud_to_scan(*load_cloud(a.in), meta, &dropped);
    if (scan.count_valid() == 0) throw InputError(a.in, "no point falls on the scan grid");
    files.stage(a.out + ".json");
    const std::string png = files.stage(a.out + ".png");
    save_scan(png.substr(0, png.size() - 4), scan);
    progress("convert", std::to_string(scan.count_valid()) + " samples, " + std::to_string(dropped) +
                            " points off the grid or out of range dropped");
  }
  files.commit();
  std::printf("%s\n", a.out.c_str());
}

}  // namespace

void add_tool_commands(CLI::App& app, const Progress& progress, Commands* out) {
  auto ra = std::make_shared<RenderArgs>();
  auto* rc = app.add_subcommand("render", "Draw a mesh (shaded) or a scan (height colours) to a PNG");
  rc->add_option("--mesh", ra->mesh, "Mesh to draw: .ply, .obj (patches.obj's Bezier patches tessellated), .off, .stl or a skin .glb");
  rc->add_option("--scan", ra->scan, "Scan to draw: its stem or either file")->transform(scan_stem_option());
  rc->add_option("--rig", ra->rig, "Rig of the mesh: views follow the hand, joints drawn as dots");
  rc->add_option("--view", ra->view, "back, palm or side")->capture_default_str();
  auto* size = rc->add_option("--size", ra->width,
                              "Picture width, px (a mesh: height 3/4 of it; a scan: default one column a point, the "
                              "height at the scan's proportions)")
                   ->capture_default_str()
                   ->check(CLI::Range(kMinPictureWidth, kMaxPictureWidth));
  rc->add_option("--out", ra->out, "PNG to write (.png)")->required();
  add_force_flag(rc, &ra->force);
  out->push_back({rc, [ra, size] {
                    ra->width_given = size->count() > 0;
                    render(*ra);
                  }});

  auto ca = std::make_shared<ConvertArgs>();
  auto* cc = app.add_subcommand("convert", "Convert between scans (<stem>) and point clouds (.ply/.pcd), or between meshes "
                                          "(any the project writes to .ply, .obj, .off or .stl, e.g. skin.glb to an STL for printing)");
  cc->add_option("--in", ca->in,
                 "Scan (its stem or either file), cloud (.ply, .pcd, or .xyz/.pts/.txt text), or mesh (.obj, .off, .stl, .glb; "
                 "patches.obj tessellated)")
      ->transform(scan_stem_option())
      ->required();
  cc->add_option("--out", ca->out, "Scan stem, .ply/.pcd cloud, or mesh (.ply, .obj, .off, .stl) by extension")->required();
  cc->add_option("--like", ca->like, "Cloud -> scan: take the grid from this scan's sidecar (default: CUBIST 512 x 512)");
  cc->add_option("--side", ca->side, "Cloud -> scan: back or palm");
  add_force_flag(cc, &ca->force);
  out->push_back({cc, [ca, &progress] { convert(*ca, progress); }});
}

}  // namespace handskin::cli
