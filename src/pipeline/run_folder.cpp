#include "pipeline/run_folder.hpp"

#include <filesystem>

#include "core/errors.hpp"
#include "core/json_util.hpp"
#include "pipeline/skin_grid.hpp"
#include "pipeline/skin_stage.hpp"
#include "pipeline/stage_options.hpp"
#include "register/registration.hpp"
#include "rigging/binding.hpp"

namespace handskin {

namespace {
bool is_input_path(const std::string& v) { return !v.empty() && v[0] != '(' && v.rfind("builtin:", 0) != 0; }
}  // namespace

void relativise_input_paths(Json* inputs, const std::string& report_dir, Json* absolute) {
  namespace fs = std::filesystem;
  static const char* const kPathKeys[] = {"back",  "palm",          "clouds", "rig",    "pipeline",   "merged",
                                          "markers", "truth",       "posture_model", "layout", "back_photo", "palm_photo"};
  const fs::path base = fs::absolute(report_dir).lexically_normal();
  *absolute = Json::object();
  auto convert = [&](const Json& v, Json* rel, Json* abs) {
    if (!v.is_string() || !is_input_path(v.get<std::string>())) {
      *rel = v, *abs = v;
      return;
    }
    const fs::path a = fs::absolute(v.get<std::string>()).lexically_normal();
    *abs = a.string();
    *rel = a.lexically_relative(base).string();
  };
  for (const char* key : kPathKeys) {
    if (!inputs->contains(key)) continue;
    const Json v = (*inputs)[key];
    if (v.is_array()) {
      Json rel = Json::array(), abs = Json::array();
      for (const Json& e : v) {
        Json r, a;
        convert(e, &r, &a);
        rel.push_back(r), abs.push_back(a);
      }
      (*inputs)[key] = rel, (*absolute)[key] = abs;
    } else {
      convert(v, &(*inputs)[key], &(*absolute)[key]);
    }
  }
}

std::string run_folder_rig(const std::string& dir, const std::string& given) {
  namespace fs = std::filesystem;
  if (!given.empty()) return given;
  if (fs::exists(fs::path(dir) / "rig_auto.json")) return (fs::path(dir) / "rig_auto.json").string();
  const fs::path report = fs::path(dir) / "report.json";
  if (fs::exists(report)) {
    const Json rep = load_json_object(report.string());
    auto named = [&](const char* section) -> std::string {
      if (!rep.contains(section) || !rep[section].is_object() || !rep[section].contains("rig") ||
          !rep[section]["rig"].is_string())
        return "";
      const std::string v = rep[section]["rig"].get<std::string>();
      return is_input_path(v) ? v : "";
    };
    const std::string rel = named("inputs"), abs = named("inputs_absolute");
    std::vector<std::string> tried;
    if (!rel.empty()) tried.push_back(fs::path(rel).is_absolute() ? rel : (fs::path(dir) / rel).lexically_normal().string());
    if (!abs.empty()) tried.push_back(abs);
    if (!rel.empty()) tried.push_back(rel);  // a report from before the paths were the folder's
    for (const std::string& t : tried)
      if (fs::is_regular_file(t)) return t;
    if (!tried.empty())
      throw UsageError("--rig", "the rig " + report.string() + " names is not there (" + tried.front() +
                                    (abs.empty() ? "" : ", nor " + abs) + "); give --rig");
  }
  throw UsageError("--rig", "no rig for " + dir + " (no rig_auto.json, no rig in its report.json); give --rig");
}

void relativise_output_paths(Json* outputs, const std::string& report_dir) {
  namespace fs = std::filesystem;
  const fs::path base = fs::absolute(report_dir).lexically_normal();
  for (auto& [key, v] : outputs->items())
    if (v.is_string()) v = fs::absolute(v.get<std::string>()).lexically_normal().lexically_relative(base).string();
}

RunFolderPatches patches_for_run_folder(const std::string& dir, const Rig& rig, const std::string& rig_path,
                                        const PipelineOptions& po,
                                        const std::optional<PatchLayout>& layout, const std::string& layout_name,
                                        const TruthSkin* truth, const std::function<void(const std::string&)>& progress) {
  RunFolderPatches p;
  p.merged = (std::filesystem::path(dir) / "merged.ply").string();
  p.rig = rig;
  progress("reading " + p.merged);
  const MergedArrays m = read_merged(p.merged);
  // The skeleton the folder's run placed (its rig_auto.json, also when given as --rig) is taken
  // as that run took it: not turned to the cloud, its skin built as on a placed skeleton (its
  // digits not carried to their tip joints). Any other rig is taken as a given one.
  namespace fs = std::filesystem;
  const fs::path auto_rig = fs::path(dir) / "rig_auto.json";
  std::error_code ec;
  const bool placed = fs::exists(auto_rig) && fs::equivalent(rig_path, auto_rig, ec);
  if (!placed)
    if (const auto note = orient_rig_to_cloud(&p.rig, m.points, m.sides); note && !note->empty())
      progress(rig_path + ": " + *note);
  // The folder's own skin (skin.ply with skin_grid.json) when it was built on this rig;
  // otherwise (a folder from before skin_grid.json, or another --rig) it is built again.
  const std::string ply = (fs::path(dir) / "skin.ply").string(), grid = (fs::path(dir) / "skin_grid.json").string();
  std::optional<SkinResult> folder_skin;
  if (fs::exists(ply) && fs::exists(grid)) {
    progress("reading " + ply + " and " + grid);
    folder_skin = read_folder_skin(ply, grid, p.rig);
    if (!folder_skin) progress("the folder's skin was built on another rig than " + rig_path);
  }
  if (!folder_skin) progress("building the skin on " + rig_path);
  SkinOptions so = skin_options(po);
  so.rig_given = !placed;
  const SkinResult skin = folder_skin ? std::move(*folder_skin) : build_skin(m.points, p.rig, so);
  PatchOptions opts = patch_options(po);
  opts.layout = layout;
  progress(std::string("fitting bicubic patches") + (layout ? " on the layout of " + layout_name : "") +
           ", correcting the parameters");
  p.result = run_patch_stage(skin, p.rig, m.points, m.sides, opts, truth, static_cast<int>(po.patches.error_grid));
  // Smooth weights for the control points, from the skin's binding as `run` makes it.
  progress(std::string("binding the control points (") + (po.rigging.smooth ? "bone-heat" : "rigid") +
           " weights of the skin)");
  bind_patch_controls(&p.result.patches, skin.mesh, bind_skin(skin.mesh, bones_from_rig(p.rig), binding_options(po)));
  return p;
}

}  // namespace handskin
