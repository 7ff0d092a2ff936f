#pragma once
/// `handskin run`: the whole pipeline from two scans and a rig to the outputs in one folder.
/// Stages so far: ingest (both scans to point clouds), registration (back into the palm
/// frame, merged cloud). Later stages add themselves here.
#include <functional>
#include <string>

#include "core/json_util.hpp"
#include "pipeline/options.hpp"
#include "register/registration.hpp"

namespace handskin {

struct RunInputs {
  std::string back_stem;   ///< `<stem>.png` + `<stem>.json`, side "back"
  std::string palm_stem;   ///< side "palm"
  std::string rig_path;    ///< hand-rig/1, palm frame; empty: the skeleton is placed automatically
  bool auto_rig = false;   ///< place the skeleton automatically even with a rig (and compare)
  std::string out_dir;
  std::string markers_path;   ///< optional handskin-markers/1 (manual marker positions)
  std::string pipeline_path;  ///< empty: built-in defaults (= pipelines/cubist.json)
  std::string truth_path;     ///< optional truth.json (synthetic pairs): the skin's errors in the report
  PipelineOptions options;
};

using ProgressFn = std::function<void(const std::string&)>;

struct RunResult {
  Json report;   ///< what report.json holds
  std::string report_path;
};

/// A side view of the merged cloud (palm samples blue-grey, back samples skin-toned, the
/// markers as red dots): how the two halves meet, at a glance. PNG bytes.
std::string merged_preview_png(const MergedArrays& merged, const std::vector<Eigen::Vector3d>& markers, int width = 1000);

/// Run every stage; outputs are written atomically into `out_dir` (created if needed), the
/// report last. Bad input throws InputError before any output is written.
RunResult run_pipeline(const RunInputs& in, const ProgressFn& progress);

}  // namespace handskin
