#pragma once
/// Work on a run folder (`handskin run`'s, or `register` + `skin`'s): what `handskin patches`
/// does with one, as a pipeline function (the CLI parses, calls and prints).
#include <functional>
#include <optional>
#include <string>

#include "core/rig.hpp"
#include "patches/layout.hpp"
#include "pipeline/options.hpp"
#include "pipeline/patch_stage.hpp"
#include "scan/truth_io.hpp"

namespace handskin {

/// The rig a run folder's skin was built on: `given` when not empty, else the folder's
/// rig_auto.json (the automatic skeleton's), else the rig its report.json names (relative to
/// the folder; else its absolute path in `inputs_absolute`; else, for a report from before
/// 2026-11-28, relative to the working directory). UsageError (naming --rig) when there is none
/// or none of those files is there.
std::string run_folder_rig(const std::string& dir, const std::string& given);

/// A report's "inputs" made to travel with its folder: every input path (the keys that name
/// files: back, palm, clouds, rig, pipeline, merged, markers, truth, posture_model, layout,
/// back_photo, palm_photo) made relative to `report_dir`, the folder the report is written in,
/// and the same paths absolute in `*absolute`. Values that are no path ("(placed
/// automatically)", "builtin:…") are left as they are.
void relativise_input_paths(Json* inputs, const std::string& report_dir, Json* absolute);

/// A report's "outputs" ({key: path}) relative to `report_dir`, the folder the report is
/// written in (the outputs lie beside it: their names), so that a moved folder's report
/// still names them.
void relativise_output_paths(Json* outputs, const std::string& report_dir);

/// The patches of a run folder, and what they were made from.
struct RunFolderPatches {
  std::string merged;  ///< the folder's merged.ply
  Rig rig;             ///< the rig, oriented to the cloud
  PatchStageResult result;
};

/// Read the folder's merged cloud and its skin (skin.ply and skin_grid.json) — or, when the
/// folder has no skin_grid.json or its skin was built on another rig, build the skin on `rig`
/// (read from `rig_path`, palm frame) with the pipeline's skin options — run the patch stage (on `layout` when given) and bind the
/// control points with the skin's weights as `run` does.
RunFolderPatches patches_for_run_folder(const std::string& dir, const Rig& rig, const std::string& rig_path,
                                        const PipelineOptions& po,
                                        const std::optional<PatchLayout>& layout, const std::string& layout_name,
                                        const TruthSkin* truth, const std::function<void(const std::string&)>& progress);

}  // namespace handskin
