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

std::string run_folder_rig(const std::string& dir, const std::string& given) {
  namespace fs = std::filesystem;
  std::string rig_path = given;
  if (rig_path.empty() && fs::exists(fs::path(dir) / "rig_auto.json")) rig_path = (fs::path(dir) / "rig_auto.json").string();
  if (rig_path.empty() && fs::exists(fs::path(dir) / "report.json")) {
    const Json rep = load_json_object((fs::path(dir) / "report.json").string());
    if (rep.contains("inputs") && rep["inputs"].contains("rig") && rep["inputs"]["rig"].is_string() &&
        rep["inputs"]["rig"].get<std::string>().rfind("(", 0) != 0)
      rig_path = rep["inputs"]["rig"].get<std::string>();
  }
  if (rig_path.empty())
    throw UsageError("--rig", "no rig for " + dir + " (no rig_auto.json, no rig in its report.json); give --rig");
  return rig_path;
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
  if (const auto note = orient_rig_to_cloud(&p.rig, m.points, m.sides); note && !note->empty())
    progress(rig_path + ": " + *note);
  // The folder's own skin (skin.ply with skin_grid.json) when it was built on this rig;
  // otherwise (a folder from before skin_grid.json, or another --rig) it is built again.
  namespace fs = std::filesystem;
  const std::string ply = (fs::path(dir) / "skin.ply").string(), grid = (fs::path(dir) / "skin_grid.json").string();
  std::optional<SkinResult> folder_skin;
  if (fs::exists(ply) && fs::exists(grid)) {
    progress("reading " + ply + " and " + grid);
    folder_skin = read_folder_skin(ply, grid, p.rig);
    if (!folder_skin) progress("the folder's skin was built on another rig than " + rig_path);
  }
  if (!folder_skin) progress("building the skin on " + rig_path);
  const SkinResult skin = folder_skin ? std::move(*folder_skin) : build_skin(m.points, p.rig, skin_options(po));
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
