#include "pipeline/options.hpp"

#include "core/errors.hpp"

namespace handskin {

bool PipelineOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (ingest.min_returns < 1) return bad("ingest.min_returns must be >= 1");
  if (markers.count < 3) return bad("markers.count must be >= 3");
  if (!(markers.radius_mm > 0 && markers.radius_mm <= 20)) return bad("markers.radius_mm must be in (0, 20]");
  if (slicing.planes < 3 || slicing.planes > 1000) return bad("slicing.planes must be in [3, 1000]");
  if (slicing.points_per_segment < 2 || slicing.points_per_segment > 200)
    return bad("slicing.points_per_segment must be in [2, 200]");
  if (patches.count < 1) return bad("patches.count must be >= 1");
  if (patches.error_grid < 2 || patches.error_grid > 2000) return bad("patches.error_grid must be in [2, 2000]");
  return true;
}

PipelineOptions parse_pipeline(const Json& j, const std::string& file) {
  if (get_string(j, "format", file) != "handskin-pipeline/1")
    throw InputError(file, "key 'format' must be \"handskin-pipeline/1\"");
  reject_unknown_keys(j, {"format", "description", "ingest", "markers", "slicing", "patches"}, file, "");
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
    o.markers.radius_mm = get_finite_or(*s, "radius_mm", o.markers.radius_mm, file + ": markers");
  }
  if (const Json* s = section("slicing")) {
    reject_unknown_keys(*s, {"planes", "points_per_segment"}, file, "slicing");
    o.slicing.planes = get_int_or(*s, "planes", o.slicing.planes, file + ": slicing", 3);
    o.slicing.points_per_segment = get_int_or(*s, "points_per_segment", o.slicing.points_per_segment, file + ": slicing", 2);
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

PipelineOptions load_pipeline(const std::string& file) { return parse_pipeline(load_json_object(file), file); }

Json pipeline_to_json(const PipelineOptions& o) {
  Json j;
  j["format"] = "handskin-pipeline/1";
  j["ingest"] = {{"min_returns", o.ingest.min_returns}};
  j["markers"] = {{"count", o.markers.count}, {"radius_mm", o.markers.radius_mm}};
  j["slicing"] = {{"planes", o.slicing.planes}, {"points_per_segment", o.slicing.points_per_segment}};
  j["patches"] = {{"count", o.patches.count}, {"error_grid", o.patches.error_grid}};
  return j;
}

}  // namespace handskin
