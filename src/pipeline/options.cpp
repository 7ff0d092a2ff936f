#include "pipeline/options.hpp"

#include <algorithm>

#include "skin/skin_mesh.hpp"

#include "core/errors.hpp"

namespace handskin {

bool PipelineOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (ingest.min_returns < 1) return bad("ingest.min_returns must be >= 1");
  if (markers.count < 3) return bad("markers.count must be >= 3");
  if (markers.radius_mm && !(*markers.radius_mm >= 1 && *markers.radius_mm <= 20))
    return bad("markers.radius_mm must be in [1, 20] (or absent: estimated from the scans)");
  if (!(registration.table_margin_mm >= 0 && registration.table_margin_mm <= 20))
    return bad("registration.table_margin_mm must be in [0, 20]");
  if (!(registration.match_tolerance_mm > 0 && registration.match_tolerance_mm <= 10))
    return bad("registration.match_tolerance_mm must be in (0, 10]");
  if (!(registration.marker_clearance_mm >= 0 && registration.marker_clearance_mm <= 10))
    return bad("registration.marker_clearance_mm must be in [0, 10]");
  if (!(registration.icp_gate_mm > 0 && registration.icp_gate_mm <= 10))
    return bad("registration.icp_gate_mm must be in (0, 10]");
  if (!(registration.icp_normal_deg > 0 && registration.icp_normal_deg <= 90))
    return bad("registration.icp_normal_deg must be in (0, 90]");
  if (!(registration.icp_trim > 0 && registration.icp_trim <= 1)) return bad("registration.icp_trim must be in (0, 1]");
  if (registration.icp_max_iterations > 200) return bad("registration.icp_max_iterations must be in [0, 200]");
  if (slicing.planes < 3 || slicing.planes > 1000) return bad("slicing.planes must be in [3, 1000]");
  if (slicing.points_per_segment < 2 || slicing.points_per_segment > 200)
    return bad("slicing.points_per_segment must be in [2, 200]");
  if (!skin_options(*this).IsValid(error)) return false;
  if (patches.count < 1) return bad("patches.count must be >= 1");
  if (patches.error_grid < 2 || patches.error_grid > 2000) return bad("patches.error_grid must be in [2, 2000]");
  return true;
}

PipelineOptions parse_pipeline(const Json& j, const std::string& file) {
  if (get_string(j, "format", file) != "handskin-pipeline/1")
    throw InputError(file, "key 'format' must be \"handskin-pipeline/1\"");
  reject_unknown_keys(j, {"format", "description", "ingest", "markers", "registration", "slicing", "skin", "patches"}, file, "");
  PipelineOptions o;
  auto section = [&](const char* name) -> const Json* {
    if (!j.contains(name)) return nullptr;
    if (!j[name].is_object()) throw InputError(file, std::string("key '") + name + "' must be an object");
    return &j[name];
  };
  if (const Json* s = section("ingest")) {
    reject_unknown_keys(*s, {"min_returns"}, file, "ingest");
    o.ingest.min_returns = get_int_or(*s, "min_returns", o.ingest.min_returns, file + ": ingest", 1);
  }
  if (const Json* s = section("markers")) {
    reject_unknown_keys(*s, {"count", "radius_mm"}, file, "markers");
    o.markers.count = get_int_or(*s, "count", o.markers.count, file + ": markers", 3);
    if (s->contains("radius_mm") && !(*s)["radius_mm"].is_null())
      o.markers.radius_mm = get_finite_or(*s, "radius_mm", 0.0, file + ": markers");
  }
  if (const Json* s = section("registration")) {
    reject_unknown_keys(*s,
                        {"table_margin_mm", "match_tolerance_mm", "marker_clearance_mm", "refine", "icp_gate_mm",
                         "icp_normal_deg", "icp_trim", "icp_max_iterations"},
                        file, "registration");
    auto& r = o.registration;
    const std::string f = file + ": registration";
    r.table_margin_mm = get_finite_or(*s, "table_margin_mm", r.table_margin_mm, f);
    r.match_tolerance_mm = get_finite_or(*s, "match_tolerance_mm", r.match_tolerance_mm, f);
    r.marker_clearance_mm = get_finite_or(*s, "marker_clearance_mm", r.marker_clearance_mm, f);
    r.refine = get_bool_or(*s, "refine", r.refine, f);
    r.icp_gate_mm = get_finite_or(*s, "icp_gate_mm", r.icp_gate_mm, f);
    r.icp_normal_deg = get_finite_or(*s, "icp_normal_deg", r.icp_normal_deg, f);
    r.icp_trim = get_finite_or(*s, "icp_trim", r.icp_trim, f);
    r.icp_max_iterations = get_int_or(*s, "icp_max_iterations", r.icp_max_iterations, f, 0);
  }
  if (const Json* s = section("slicing")) {
    reject_unknown_keys(*s, {"planes", "points_per_segment"}, file, "slicing");
    o.slicing.planes = get_int_or(*s, "planes", o.slicing.planes, file + ": slicing", 3);
    o.slicing.points_per_segment = get_int_or(*s, "points_per_segment", o.slicing.points_per_segment, file + ": slicing", 2);
  }
  if (const Json* s = section("skin")) {
    reject_unknown_keys(*s, {"thumb_overlap_mm", "smoothing_rings", "wrinkle_mm", "cap_rings", "max_triangles",
                             "decimation_tolerance_mm", "slices_json", "baseline"},
                        file, "skin");
    auto& k = o.skin;
    const std::string f = file + ": skin";
    k.thumb_overlap_mm = get_finite_or(*s, "thumb_overlap_mm", k.thumb_overlap_mm, f);
    k.smoothing_rings = get_int_or(*s, "smoothing_rings", k.smoothing_rings, f, 0);
    k.wrinkle_mm = get_finite_or(*s, "wrinkle_mm", k.wrinkle_mm, f);
    k.cap_rings = get_int_or(*s, "cap_rings", k.cap_rings, f, 1);
    k.max_triangles = get_int_or(*s, "max_triangles", k.max_triangles, f, 0);
    k.decimation_tolerance_mm = get_finite_or(*s, "decimation_tolerance_mm", k.decimation_tolerance_mm, f);
    k.slices_json = get_bool_or(*s, "slices_json", k.slices_json, f);
    k.baseline = get_bool_or(*s, "baseline", k.baseline, f);
  }
  if (const Json* s = section("patches")) {
    reject_unknown_keys(*s, {"count", "error_grid"}, file, "patches");
    o.patches.count = get_int_or(*s, "count", o.patches.count, file + ": patches", 1);
    o.patches.error_grid = get_int_or(*s, "error_grid", o.patches.error_grid, file + ": patches", 2);
  }
  std::string err;
  if (!o.IsValid(&err)) throw InputError(file, err);
  return o;
}

RegistrationOptions registration_options(const PipelineOptions& o) {
  RegistrationOptions r;
  r.expected_markers = o.markers.count;
  r.estimate_radius = !o.markers.radius_mm;
  if (o.markers.radius_mm) r.spheres.radius_mm = *o.markers.radius_mm;
  r.prepare.table_margin_mm = o.registration.table_margin_mm;
  r.match_tolerance_mm = o.registration.match_tolerance_mm;
  r.marker_clearance_mm = o.registration.marker_clearance_mm;
  r.refine_enabled = o.registration.refine;
  r.refine.gate_mm = o.registration.icp_gate_mm;
  r.refine.normal_deg = o.registration.icp_normal_deg;
  r.refine.trim = o.registration.icp_trim;
  r.refine.max_iterations = static_cast<int>(o.registration.icp_max_iterations);
  return r;
}

SkinOptions skin_options(const PipelineOptions& o) {
  SkinOptions s;
  s.slicing.planes = static_cast<int>(o.slicing.planes);
  s.slicing.points_per_segment = static_cast<int>(o.slicing.points_per_segment);
  s.thumb_overlap_mm = o.skin.thumb_overlap_mm;
  s.smoothing_rings = static_cast<int>(std::min(o.skin.smoothing_rings, 1000L));
  s.wrinkle_mm = o.skin.wrinkle_mm;
  s.cap_rings = static_cast<int>(std::min(o.skin.cap_rings, 1000L));
  s.max_triangles = static_cast<int>(std::min(o.skin.max_triangles, 100000000L));
  s.decimation_tolerance_mm = o.skin.decimation_tolerance_mm;
  return s;
}

PipelineOptions load_pipeline(const std::string& file) { return parse_pipeline(load_json_object(file), file); }

Json pipeline_to_json(const PipelineOptions& o) {
  Json j;
  j["format"] = "handskin-pipeline/1";
  j["ingest"] = {{"min_returns", o.ingest.min_returns}};
  j["markers"] = {{"count", o.markers.count},
                  {"radius_mm", o.markers.radius_mm ? Json(*o.markers.radius_mm) : Json(nullptr)}};
  const auto& r = o.registration;
  j["registration"] = {{"table_margin_mm", r.table_margin_mm},     {"match_tolerance_mm", r.match_tolerance_mm},
                       {"marker_clearance_mm", r.marker_clearance_mm}, {"refine", r.refine},
                       {"icp_gate_mm", r.icp_gate_mm},             {"icp_normal_deg", r.icp_normal_deg},
                       {"icp_trim", r.icp_trim},                   {"icp_max_iterations", r.icp_max_iterations}};
  j["slicing"] = {{"planes", o.slicing.planes}, {"points_per_segment", o.slicing.points_per_segment}};
  const auto& k = o.skin;
  j["skin"] = {{"thumb_overlap_mm", k.thumb_overlap_mm}, {"smoothing_rings", k.smoothing_rings},
               {"wrinkle_mm", k.wrinkle_mm}, {"cap_rings", k.cap_rings}, {"max_triangles", k.max_triangles},
               {"decimation_tolerance_mm", k.decimation_tolerance_mm}, {"slices_json", k.slices_json},
               {"baseline", k.baseline}};
  j["patches"] = {{"count", o.patches.count}, {"error_grid", o.patches.error_grid}};
  return j;
}

}  // namespace handskin
