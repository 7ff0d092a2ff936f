#include "pipeline/registration_stage.hpp"

#include "core/atomic_file.hpp"
#include "render/preview.hpp"

namespace handskin {

std::string merged_preview_png(const MergedArrays& m, const std::vector<Eigen::Vector3d>& markers, int width) {
  std::vector<Eigen::Vector3f> c;
  c.reserve(m.sides.size());
  for (const std::uint32_t side : m.sides)
    c.push_back(side == kSideBack ? Eigen::Vector3f(0.87f, 0.72f, 0.62f) : Eigen::Vector3f(0.55f, 0.65f, 0.85f));
  RenderOptions ro;
  ro.width = width;
  ro.height = width / 2;
  ro.view = principal_view(m.points);
  ro.points = markers;
  return render_points_png(m.points, m.normals, c, ro);
}

Json registration_against_truth(const Registration& reg, const TruthSkin& truth) {
  const std::vector<Eigen::Vector3d> skin = mesh_vertices(truth.skin);
  Json t;
  for (const auto& [name, T] : {std::pair<const char*, Eigen::Isometry3d>{"marker_only", reg.marker_only},
                                {"chosen", reg.back_to_palm}}) {
    const RegistrationError e = registration_error(T, truth.back_to_palm, skin);
    t[name] = {{"rotation_deg", e.rotation_deg}, {"skin_mean_mm", e.mean_mm}, {"skin_max_mm", e.max_mm}};
  }
  t["file"] = truth.path;
  return t;
}

Json registration_summary_json(const Registration& reg) {
  const RegistrationFigures& f = reg.figures;
  Json timings = Json::object();
  for (const auto& [k, v] : f.timings_ms) timings[k] = v;
  return {{"status", reg.warnings.empty() ? "ok" : "ok_with_warnings"},
          {"warnings", reg.warnings},
          {"method", reg.refined ? "refined" : "markers"},
          {"marker_radius_mm", {{"value", reg.marker_radius_mm}, {"source", f.radius_estimated ? "estimated" : "given"}}},
          {"markers_found", {{"back", f.markers_back}, {"palm", f.markers_palm}}},
          {"markers_matched", f.markers_matched},
          {"marker_only_rms_mm", f.marker_only_rms_mm},
          {"refined_rms_mm", f.refined_rms_mm},
          {"sphere_rms_mm", {{"marker_only", f.sphere_rms_marker_only_mm}, {"refined", f.sphere_rms_refined_mm}}},
          {"icp_overlap_fraction", f.icp_overlap_fraction},
          {"uncertainty", f.rotation_sigma_deg > 0 ? Json{{"rotation_deg", f.rotation_sigma_deg},
                                                          {"displacement_mm", f.displacement_sigma_mm}}
                                                    : Json(nullptr)},
          {"merged_points", f.merged_points},
          {"timings_ms", timings}};
}

const std::vector<std::string>& registration_output_names() {
  static const std::vector<std::string> names = {"registration.json", "merged.ply", "merged.png"};
  return names;
}

Json write_registration_outputs(OutputSet& out, const Registration& reg, const Json& report) {
  save_json(out.stage("registration.json"), report);
  save_merged(out.stage("merged.ply"), *reg.merged);
  write_file_atomic(out.stage("merged.png"), merged_preview_png(merged_arrays(*reg.merged), reg.markers_palm));
  return {{"registration", out.final_path("registration.json")},
          {"merged_cloud", out.final_path("merged.ply")},
          {"merged_preview", out.final_path("merged.png")}};
}

}  // namespace handskin
