#include "pipeline/skin_stage.hpp"

#include <chrono>
#include <filesystem>
#include <optional>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "render/preview.hpp"
#include "skin/auto_rig.hpp"
#include "skin/baseline.hpp"
#include "skin/skin_mesh.hpp"
#include "skin/slices.hpp"
#include "synth/mesh_distance.hpp"

namespace handskin {

namespace {
namespace fs = std::filesystem;

// A given rig farther than this (mean over the joints) from the automatic placement is
// reported: the placement itself is within ~2.5 mm on the synthetic hands (docs/skin.md).
constexpr double kRigDisagreementMm = 8.0;

double since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

Json distance_json(const OneWayDistance& d) {
  return {{"mean", d.mean}, {"median", d.median}, {"p95", d.p95}, {"max", d.max},
          {"within_1mm", d.within_1mm}, {"samples", d.samples}};
}

// At most `limit` points, every k-th: distances from the whole cloud would cost more than
// building the skin.
std::vector<Eigen::Vector3d> thinned(const std::vector<Eigen::Vector3d>& p, size_t limit) {
  const size_t step = thinning_step(p.size(), limit);
  std::vector<Eigen::Vector3d> out;
  for (size_t i = 0; i < p.size(); i += step) out.push_back(p[i]);
  return out;
}

Json health_json(const MeshHealth& h) {
  return {{"vertices", h.vertices}, {"triangles", h.faces}, {"closed", h.closed()}, {"manifold", h.manifold()},
          {"components", h.components}, {"outward", h.volume_mm3 > 0}, {"volume_mm3", h.volume_mm3},
          {"area_mm2", h.area_mm2}};
}
}  // namespace

Rig load_palm_rig(const std::string& path) {
  Rig rig = load_rig(path);
  if (rig.frame != "palm")
    throw InputError(path, "key 'frame' is \"" + rig.frame + "\"; the skin needs joints in the palm frame");
  return rig;
}

TruthSkin load_truth_skin(const std::string& path) {
  TruthSkin t;
  t.path = path;
  t.json = load_json_object(path);
  if (get_string(t.json, "format", path) != "handskin-truth/1")
    throw InputError(path, "key 'format' must be \"handskin-truth/1\"");
  t.skin_path = (fs::path(path).parent_path() / get_string(t.json, "skin", path)).string();
  t.skin = load_mesh(t.skin_path);
  if (t.json.contains("markers_palm") && t.json["markers_palm"].is_array())
    for (const auto& m : t.json["markers_palm"]) t.markers.push_back(to_vec3(m, "markers_palm", path));
  t.exclude_mm = t.json.value("marker_radius_mm", 4.0) + 3.0;
  return t;
}

Json run_skin_stage(const SkinStageInputs& in, const PipelineOptions& options,
                    const std::function<void(const std::string&)>& progress) {
  const SkinOptions so = skin_options(options);  // checked by build_skin (and when the pipeline was read)
  // --- the skeleton: given, or placed in the cloud (and compared with the given one) ---
  const bool automatic = in.auto_rig || !in.rig;
  Json skeleton;
  std::vector<std::string> warnings;
  std::optional<AutoRig> placed;
  // The automatic placement also checks a given rig: a rig from another scan or with
  // fingers swapped still gives a closed skin, but a wrongly bound one.
  const auto ta = std::chrono::steady_clock::now();
  try {
    if (automatic) progress("placing the skeleton in the cloud");
    placed = place_skeleton(in.points, in.sides);
  } catch (const InputError& e) {
    if (automatic) throw;
    skeleton["automatic"] = {{"failed", e.what()}};
  }
  if (placed) {
    skeleton["automatic"] = {{"seconds", since(ta)}, {"scale", placed->scale},
                             {"palm_radius_mm", placed->palm_radius_mm}, {"notes", placed->notes}};
    if (in.rig) {
      const JointError e = joint_error(placed->rig, *in.rig);
      skeleton["automatic"]["against_given_rig"] = {{"mean_joint_error_mm", e.mean_mm}, {"max_joint_error_mm", e.max_mm},
                                                    {"worst_joint", e.worst_joint}};
      progress("automatic skeleton: mean joint error " + std::to_string(e.mean_mm).substr(0, 4) + " mm against the given rig");
      if (e.mean_mm > kRigDisagreementMm)
        warnings.push_back("the given rig lies " + std::to_string(e.mean_mm).substr(0, 4) +
                           " mm (mean) from the skeleton placed in the cloud (worst: " + e.worst_joint +
                           "); is it this scan's rig, with the fingers in order?");
    }
  }
  const Rig& rig = automatic ? placed->rig : *in.rig;
  skeleton["used"] = automatic ? "automatic" : "given";

  progress("building the strips (" + std::to_string(so.slicing.planes) + " planes, " +
           std::to_string(so.slicing.points_per_segment) + " points per segment)");
  const auto t0 = std::chrono::steady_clock::now();
  const SkinResult skin = build_skin(in.points, rig, so, progress);
  const double build_seconds = since(t0);
  warnings.insert(warnings.end(), skin.warnings.begin(), skin.warnings.end());
  for (const auto& w : warnings) progress("warning: " + w);
  if (!skin.watertight())
    throw InputError("merged cloud", std::string("the skin is not a closed, manifold, outward, self-intersection-free "
                                                 "surface (") +
                                         std::to_string(skin.health.boundary_edges) + " boundary edges, " +
                                         std::to_string(skin.health.nonmanifold_vertices) + " non-manifold vertices, " +
                                         std::to_string(skin.health.components) + " components" +
                                         (skin.self_intersects ? ", self-intersecting" : "") + "); nothing written");

  Json j;
  j["name"] = "skin";
  j["seconds"] = build_seconds;
  j["skeleton"] = skeleton;
  j["mesh"] = health_json(skin.health);
  j["mesh"]["self_intersections"] = skin.self_intersects;
  j["mesh"]["watertight"] = skin.watertight();
  j["triangles_before_decimation"] = skin.triangles_before_decimation;
  j["pockets_removed"] = skin.pockets_removed;
  j["timings_ms"] = {{"rings", 1000 * skin.seconds_rings}, {"stitch", 1000 * skin.seconds_union},
                     {"decimate", 1000 * skin.seconds_decimation}, {"checks", 1000 * skin.seconds_checks}};
  Json tubes = Json::array();
  for (const auto& t : skin.tubes)
    tubes.push_back({{"name", t.name}, {"present", t.present}, {"points", t.points}, {"rings", t.rings},
                     {"measured", t.measured}, {"filled", t.filled}, {"axis_offset_mm", t.axis_offset_mm},
                     {"section_radius_mm", t.section_radius_mm}});
  j["tubes"] = tubes;
  Json webs = Json::array();
  for (const auto& w : skin.webs) webs.push_back(to_json(w));
  j["webs_hand_frame"] = webs;
  Json bones = Json::array();
  for (const auto& b : skin.bones) bones.push_back(b.name());
  j["bones"] = bones;
  j["warnings"] = warnings;

  progress("measuring the cloud against the skin");
  const MeshDistance to_skin(skin.mesh);
  const auto cloud = thinned(in.points, 20000);
  j["cloud_to_skin_mm"] = distance_json(one_way_distance(cloud, to_skin));

  // --- files (each written through a temporary and renamed) ---
  ensure_directory(in.out_dir);
  Json outputs;
  const std::string ply = (fs::path(in.out_dir) / "skin.ply").string();
  const std::string obj = (fs::path(in.out_dir) / "skin.obj").string();
  const std::string png = (fs::path(in.out_dir) / "skin.png").string();
  save_skin_ply(ply, skin);
  save_mesh(obj, skin.mesh);
  RenderOptions ro;
  ro.width = 900;
  ro.height = 500;
  ro.view = hand_frame_from_rig(rig).linear();  // looking at the back, fingers to the right
  write_file_atomic(png, render_mesh_png({&skin.mesh}, ro));
  outputs["skin_ply"] = ply;
  outputs["skin_obj"] = obj;
  outputs["skin_png"] = png;
  if (automatic) {
    const std::string rp = (fs::path(in.out_dir) / "rig_auto.json").string();
    save_rig(rp, placed->rig);
    outputs["rig_auto"] = rp;
  }
  if (options.skin.slices_json) {
    const std::string sj = (fs::path(in.out_dir) / "slices.json").string();
    save_json(sj, slicing_to_json(slice_cloud(in.points, rig, so.slicing)));
    outputs["slices_json"] = sj;
  }

  std::optional<BaselineResult> baseline;
  std::optional<MeshDistance> to_base;
  if (options.skin.baseline) {
    progress("baseline: CGAL Poisson reconstruction of the same cloud (for comparison)");
    baseline = poisson_baseline(in.points, in.normals);
    const std::string bp = (fs::path(in.out_dir) / "baseline.ply").string();
    save_mesh(bp, baseline->mesh);
    outputs["baseline_ply"] = bp;
    to_base.emplace(baseline->mesh);
    j["baseline"] = {{"method", "CGAL poisson_surface_reconstruction_delaunay"},
                     {"seconds", baseline->seconds},
                     {"points_used", baseline->points_used},
                     {"mesh", health_json(mesh_health(baseline->mesh))},
                     {"cloud_to_baseline_mm", distance_json(one_way_distance(cloud, *to_base))}};
  }

  if (in.truth) {
    const TruthSkin& t = *in.truth;
    progress("comparing with the true skin of " + t.path);
    const MeshDistance to_truth(t.skin);
    const auto ours = sample_surface(skin.mesh, 4.0), theirs = sample_surface(t.skin, 4.0);
    j["truth"] = {{"file", t.skin_path},
                  {"excluded_within_mm_of_markers", t.exclude_mm},
                  {"skin_to_truth_mm", distance_json(one_way_distance(ours, to_truth, t.markers, t.exclude_mm))},
                  {"truth_to_skin_mm", distance_json(one_way_distance(theirs, to_skin, t.markers, t.exclude_mm))}};
    if (baseline) {
      j["truth"]["baseline_to_truth_mm"] =
          distance_json(one_way_distance(sample_surface(baseline->mesh, 4.0), to_truth, t.markers, t.exclude_mm));
      j["truth"]["truth_to_baseline_mm"] = distance_json(one_way_distance(theirs, *to_base, t.markers, t.exclude_mm));
    }
  }
  j["outputs"] = outputs;
  return j;
}

}  // namespace handskin
