#include "pipeline/skin_grid.hpp"

#include "core/errors.hpp"
#include "mesh/mesh.hpp"

namespace handskin {

namespace {
constexpr const char* kFormat = "handskin-skin-grid/1";

Json points_json(const std::vector<Eigen::Vector3d>& pts) {
  Json a = Json::array();
  for (const auto& p : pts) a.push_back(to_json(p));
  return a;
}

std::vector<Eigen::Vector3d> points_of(const Json& a, const std::string& what, const std::string& file) {
  if (!a.is_array()) throw InputError(file, "'" + what + "' must be an array of [x, y, z]");
  std::vector<Eigen::Vector3d> out;
  out.reserve(a.size());
  for (size_t k = 0; k < a.size(); ++k) out.push_back(to_vec3(a[k], what + "[" + std::to_string(k) + "]", file));
  return out;
}
}  // namespace

Json skin_grid_to_json(const SkinResult& skin, const Rig& rig) {
  Json j;
  j["format"] = kFormat;
  j["units"] = "mm";
  j["rig_joints"] = points_json(std::vector<Eigen::Vector3d>(rig.joints.begin(), rig.joints.end()));
  j["webs_hand_frame"] = points_json(skin.webs);
  Json tubes = Json::array();
  for (int t = 0; t < kSkinTubes; ++t) {
    Json e;
    e["tube"] = skin_tube_name(t);
    const bool have_report = t < static_cast<int>(skin.tubes.size()), have_grid = t < static_cast<int>(skin.grid.size());
    e["present"] = have_report && skin.tubes[t].present && have_grid && skin.grid[t].present;
    e["section_radius_mm"] = have_report ? skin.tubes[t].section_radius_mm : 0.0;
    Json rings = Json::array();
    if (have_grid) {
      for (const auto& r : skin.grid[t].rings) rings.push_back(points_json(r));
      e["station"] = skin.grid[t].station;
      e["pole"] = skin.grid[t].pole ? to_json(*skin.grid[t].pole) : Json(nullptr);
    } else {
      e["station"] = Json::array();
      e["pole"] = nullptr;
    }
    e["rings"] = std::move(rings);
    tubes.push_back(std::move(e));
  }
  j["tubes"] = std::move(tubes);
  return j;
}

std::optional<SkinResult> read_folder_skin(const std::string& skin_ply, const std::string& grid_json, const Rig& rig) {
  const Json j = load_json_object(grid_json);
  if (get_string(j, "format", grid_json) != kFormat)
    throw InputError(grid_json, "key 'format' must be \"" + std::string(kFormat) + "\"");
  const std::vector<Eigen::Vector3d> joints = points_of(require(j, "rig_joints", grid_json), "rig_joints", grid_json);
  if (joints.size() != rig.joints.size())
    throw InputError(grid_json, "'rig_joints' holds " + std::to_string(joints.size()) + " joints, not " +
                                    std::to_string(rig.joints.size()));
  for (size_t k = 0; k < joints.size(); ++k)
    if ((joints[k] - rig.joints[k]).norm() > 1e-6) return std::nullopt;
  SkinResult s;
  s.mesh = load_mesh(skin_ply);
  s.bones = bones_from_rig(rig);
  s.webs = points_of(require(j, "webs_hand_frame", grid_json), "webs_hand_frame", grid_json);
  const Json& tubes = require(j, "tubes", grid_json);
  if (!tubes.is_array() || tubes.size() != static_cast<size_t>(kSkinTubes))
    throw InputError(grid_json, "'tubes' must hold " + std::to_string(kSkinTubes) + " tubes");
  for (int t = 0; t < kSkinTubes; ++t) {
    const Json& e = tubes[static_cast<size_t>(t)];
    const std::string where = "tubes[" + std::to_string(t) + "]";
    if (!e.is_object()) throw InputError(grid_json, "'" + where + "' must be an object");
    if (get_string(e, "tube", grid_json) != skin_tube_name(t))
      throw InputError(grid_json, "'" + where + ".tube' must be \"" + skin_tube_name(t) + "\"");
    SkinTubeReport rep;
    rep.present = get_bool_or(e, "present", false, grid_json);
    rep.section_radius_mm = get_finite(e, "section_radius_mm", grid_json);
    RingGrid g;
    g.tube = t;
    g.present = rep.present;
    const Json& rings = require(e, "rings", grid_json);
    if (!rings.is_array()) throw InputError(grid_json, "'" + where + ".rings' must be an array of rings");
    for (size_t r = 0; r < rings.size(); ++r) {
      g.rings.push_back(points_of(rings[r], where + ".rings[" + std::to_string(r) + "]", grid_json));
      if (g.rings.back().size() != g.rings.front().size())
        throw InputError(grid_json, "'" + where + ".rings[" + std::to_string(r) + "]' holds " +
                                        std::to_string(g.rings.back().size()) + " points, the first ring " +
                                        std::to_string(g.rings.front().size()));
    }
    const Json& station = require(e, "station", grid_json);
    if (!station.is_array() || station.size() != g.rings.size())
      throw InputError(grid_json, "'" + where + ".station' must hold one integer per ring");
    for (size_t r = 0; r < station.size(); ++r) {
      if (!station[r].is_number_integer() || station[r].get<long long>() < -1 || station[r].get<long long>() > 100000)
        throw InputError(grid_json, "'" + where + ".station' must hold integers from -1 (a dome ring) to 100000");
      g.station.push_back(static_cast<int>(station[r].get<long long>()));
    }
    const Json& pole = require(e, "pole", grid_json);
    if (!pole.is_null()) g.pole = to_vec3(pole, where + ".pole", grid_json);
    s.tubes.push_back(rep);
    s.grid.push_back(std::move(g));
  }
  return s;
}

}  // namespace handskin
