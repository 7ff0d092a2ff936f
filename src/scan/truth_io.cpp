#include "scan/truth_io.hpp"

#include <filesystem>

#include "core/errors.hpp"
#include "core/json_util.hpp"
#include "core/transform.hpp"

namespace handskin {

TruthSkin load_truth_skin(const std::string& path) {
  namespace fs = std::filesystem;
  TruthSkin t;
  t.path = path;
  const Json json = load_json_object(path);
  if (get_string(json, "format", path) != "handskin-truth/1")
    throw InputError(path, "key 'format' must be \"handskin-truth/1\"");
  t.back_to_palm = isometry_from_json(require(json, "back_to_palm", path), "back_to_palm", path);
  t.skin_path = (fs::path(path).parent_path() / get_string(json, "skin", path)).string();
  t.skin = load_mesh(t.skin_path);
  if (json.contains("markers_palm")) {
    if (!json["markers_palm"].is_array()) throw InputError(path, "key 'markers_palm' must be an array");
    for (const auto& m : json["markers_palm"]) t.markers.push_back(to_vec3(m, "markers_palm", path));
  }
  t.exclude_mm = get_finite_or(json, "marker_radius_mm", 4.0, path) + 3.0;
  return t;
}

}  // namespace handskin
