#include "pipeline/registration_stage.hpp"

#include <cmath>

#include "core/atomic_file.hpp"
#include "core/transform.hpp"
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
  const std::vector<Eigen::Vector3d> skin = truth.skin.vertices;
  Json t;
  for (const auto& [name, T] : {std::pair<const char*, Eigen::Isometry3d>{"marker_only", reg.marker_only},
                                {"chosen", reg.back_to_palm}}) {
    const RegistrationError e = registration_error(T, truth.back_to_palm, skin);
    t[name] = {{"rotation_deg", e.rotation_deg}, {"skin_mean_mm", e.mean_mm}, {"skin_max_mm", e.max_mm}};
  }
  t["file"] = truth.path;
  return t;
}

namespace {

Json round_vec(const Eigen::Vector3d& v) {
  auto r = [](double x) { return std::round(x * 1e4) / 1e4; };
  return Json::array({r(v.x()), r(v.y()), r(v.z())});
}

Json residuals_json(const MarkerResiduals& m) {
  Json a = Json::array();
  for (double d : m.per_pair_mm) a.push_back(std::round(d * 1e5) / 1e5);
  return a;
}

Json radius_json(const MarkerRadiusDetail& d) {
  Json j = {{"source", d.estimated ? "estimated" : "given"}, {"radius_mm", d.radius_mm}};
  if (!d.estimated) return j;
  Json tried = Json::array();
  for (const RadiusTry& t : d.tried)
    tried.push_back({{"radius_mm", t.radius_mm},
                     {"palm", t.palm},
                     {"back", t.back_searched ? Json(t.back) : Json(nullptr)},
                     {"matched", t.back_searched ? Json(t.matched) : Json(nullptr)}});
  j["tried"] = tried;
  j["refinement_mm"] = d.refinement_mm;
  j["candidate_mm"] = d.candidate_mm;
  j["caps"] = d.caps;
  j["spread_mm"] = d.spread_mm;
  if (d.free_fit_tolerance_mm > 0) j["free_fit_tolerance_mm"] = d.free_fit_tolerance_mm;
  return j;
}

Json scan_json(const ScanRegistrationDetail& s) {
  Json j;
  if (s.manual_markers) {
    j["marker_source"] = "manual";
  } else {
    j["marker_source"] = "detected";
    j["candidates_examined"] = s.candidates_examined;
    Json rej = Json::array();
    for (const auto& c : s.rejected)
      rej.push_back({{"near", round_vec(c.centre)}, {"votes", c.votes}, {"reason", c.rejected_because}});
    j["rejected_candidates"] = rej;
    if (s.candidates_dropped > 0) j["candidates_dropped"] = s.candidates_dropped;
  }
  j["returns"] = s.returns;
  j["table"] = {{"plane", {s.table_plane(0), s.table_plane(1), s.table_plane(2), s.table_plane(3)}},
                {"tilt_deg", s.table_tilt_deg},
                {"rms_mm", s.table_rms_mm},
                {"points", s.table_points}};
  j["below_table"] = s.below_table;
  j["speckle"] = {{"islands", s.speckle_islands}, {"points", s.speckle_points}};
  j["object_points"] = s.object_points;
  Json a = Json::array();
  for (size_t k = 0; k < s.markers.size(); ++k)
    a.push_back({{"centre", round_vec(s.markers[k].centre)},
                 {"radius_free_fit_mm", s.markers[k].radius_free},
                 {"rms_mm", s.markers[k].rms_mm},
                 {"samples", s.markers[k].inliers.size()},
                 {"spread_deg", s.markers[k].spread_deg},
                 {"matched_with", s.partner[k] >= 0 ? Json(s.partner[k]) : Json(nullptr)}});
  j["markers"] = a;
  return j;
}

Json timings_json(const RegistrationFigures& f) {
  Json timings = Json::object();
  for (const auto& [k, v] : f.timings_ms) timings[k] = v;
  return timings;
}

}  // namespace

Json registration_to_json(const Registration& reg) {
  const RegistrationDetail& d = reg.detail;
  const RegistrationOptions& o = d.used;
  const RefineResult& ref = d.refinement;
  Json rep;
  rep["format"] = "handskin-registration/1";
  rep["status"] = reg.warnings.empty() ? "ok" : "ok_with_warnings";
  rep["marker_radius"] = radius_json(d.radius);
  const RegistrationUncertainty& u = d.uncertainty;
  rep["uncertainty"] = u.valid ? Json{{"rotation_deg", u.rotation_deg},
                                      {"displacement_mm", u.displacement_mm},
                                      {"displacement_markers_mm", u.displacement_markers_mm},
                                      {"radius_mm", u.radius_mm > 0 ? Json(u.radius_mm) : Json(nullptr)},
                                      {"residual_sigma_mm", u.residual_sigma_mm}}
                               : Json(nullptr);
  rep["warnings"] = reg.warnings;
  rep["back_to_palm"] = isometry_to_json(reg.back_to_palm);
  rep["method"] = reg.refined ? "refined" : "markers";
  rep["scans"] = {{"back", scan_json(d.back)}, {"palm", scan_json(d.palm)}};
  Json pairs = Json::array();
  for (const auto& [b, p] : d.match.pairs) pairs.push_back({b, p});
  rep["matching"] = {{"pairs_back_palm", pairs},
                     {"tolerance_mm", o.match_tolerance_mm},
                     {"recovered", d.recovered},
                     {"left_out", d.left_out},
                     {"hypotheses", d.match.hypotheses},
                     {"runner_up_pairs", d.match.runner_up_pairs},
                     {"runner_up_rms_mm", d.match.runner_up_rms_mm}};
  rep["marker_only"] = {{"back_to_palm", isometry_to_json(reg.marker_only)},
                        {"marker_residuals_mm", residuals_json(d.marker_only)},
                        {"rms_mm", d.marker_only.rms_mm},
                        {"max_mm", d.marker_only.max_mm},
                        {"sphere_rms_mm", ref.marker_rms_start}};
  rep["refined"] = {{"enabled", o.refine_enabled},
                    {"accepted", reg.refined},
                    {"note", ref.note},
                    {"back_to_palm", isometry_to_json(ref.T)},
                    {"marker_residuals_mm", residuals_json(d.refined)},
                    {"rms_mm", d.refined.rms_mm},
                    {"max_mm", d.refined.max_mm},
                    {"sphere_rms_mm", ref.marker_rms_end},
                    {"icp",
                     {{"iterations", ref.iterations},
                      {"converged", ref.converged},
                      {"surface_pairs", ref.surface_pairs},
                      {"gated_pairs", ref.gated_pairs},
                      {"min_surface_pairs", o.refine.min_surface_pairs},
                      {"tried", ref.surface_tried},
                      {"overlap_fraction", ref.overlap_fraction},
                      {"inlier_rms_mm", ref.surface_rms_mm},
                      {"gate_mm", o.refine.gate_mm},
                      {"normal_deg", o.refine.normal_deg},
                      {"trim", o.refine.trim}}},
                    {"change_from_marker_only",
                     {{"rotation_deg", d.change_rotation_deg}, {"translation_mm", d.change_translation_mm}}}};
  rep["accept_residual_mm"] = d.accept_residual_mm;
  Json mk = Json::array();
  for (const auto& c : reg.markers_palm) mk.push_back(round_vec(c));
  rep["markers_palm"] = mk;
  rep["merged"] = {{"points", reg.merged ? reg.merged->size() : size_t{0}},
                   {"palm", d.merged_palm},
                   {"back", d.merged_back},
                   {"marker_samples_removed", d.marker_samples_removed}};
  rep["timings_ms"] = timings_json(reg.figures);
  return rep;
}

Json registration_summary_json(const Registration& reg) {
  const RegistrationFigures& f = reg.figures;
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
          {"timings_ms", timings_json(f)}};
}

const std::vector<std::string>& registration_output_names() {
  static const std::vector<std::string> names = {"registration.json", "merged.ply", "merged.png"};
  return names;
}

std::string merged_preview_png(const Registration& reg) {
  return merged_preview_png(merged_arrays(*reg.merged), reg.markers_palm);
}

Json write_registration_outputs(OutputSet& out, const Registration& reg, const Json& report,
                                const std::string& merged_png) {
  save_json(out.stage("registration.json"), report);
  save_merged(out.stage("merged.ply"), *reg.merged);
  write_file_atomic(out.stage("merged.png"), merged_png);
  return {{"registration", out.final_path("registration.json")},
          {"merged_cloud", out.final_path("merged.ply")},
          {"merged_preview", out.final_path("merged.png")}};
}

}  // namespace handskin
