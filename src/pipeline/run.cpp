#include "pipeline/run.hpp"

#include <chrono>
#include <filesystem>
#include <optional>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/rig.hpp"
#include "register/registration.hpp"
#include "render/preview.hpp"
#include "scan/cloud.hpp"
#include "scan/cubist_io.hpp"
#include "pipeline/skin_stage.hpp"

namespace handskin {

namespace {
class StageTimer {
 public:
  StageTimer() : t0_(std::chrono::steady_clock::now()) {}
  double seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count(); }

 private:
  std::chrono::steady_clock::time_point t0_;
};

Json scan_figures(const RangeScan& scan, const std::string& stem) {
  return {{"stem", stem},
          {"side", side_name(scan.meta.side)},
          {"scanlines", scan.meta.scanlines},
          {"points", scan.meta.points},
          {"returns", scan.count_valid()},
          {"no_return", scan.values.size() - scan.count_valid()}};
}
}  // namespace

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

RunResult run_pipeline(const RunInputs& in, const ProgressFn& progress) {
  const StageTimer total;
  Json report;
  report["format"] = "handskin-report/1";
  report["inputs"] = {{"back", in.back_stem}, {"palm", in.palm_stem}, {"rig", in.rig_path.empty() ? "(placed automatically)" : in.rig_path},
                      {"pipeline", in.pipeline_path.empty() ? "(built-in defaults)" : in.pipeline_path}};
  report["pipeline"] = pipeline_to_json(in.options);
  Json stages = Json::array();

  // --- ingest: read and check every input before anything is written ---
  progress("ingest: reading scans and rig");
  const StageTimer t_ingest;
  const RangeScan back = load_scan_side(in.back_stem, ScanSide::Back, "--back");
  const RangeScan palm = load_scan_side(in.palm_stem, ScanSide::Palm, "--palm");
  for (const auto* s : {&back, &palm})
    if (static_cast<long>(s->count_valid()) < in.options.ingest.min_returns)
      throw InputError((s == &back ? in.back_stem : in.palm_stem) + ".png",
                       "only " + std::to_string(s->count_valid()) + " measured samples (ingest.min_returns is " +
                           std::to_string(in.options.ingest.min_returns) + ")");
  std::optional<Rig> rig;
  if (!in.rig_path.empty()) rig = load_palm_rig(in.rig_path);
  std::optional<TruthSkin> truth;  // read before any work, so a bad file fails early
  if (!in.truth_path.empty()) truth = load_truth_skin(in.truth_path);
  MarkerHints hints;
  if (!in.markers_path.empty()) hints = load_marker_hints(in.markers_path);
  const Cloud::Ptr back_cloud = dense_copy(*scan_to_organized_cloud(back));
  const Cloud::Ptr palm_cloud = dense_copy(*scan_to_organized_cloud(palm));
  stages.push_back({{"name", "ingest"},
                    {"seconds", t_ingest.seconds()},
                    {"back", scan_figures(back, in.back_stem)},
                    {"palm", scan_figures(palm, in.palm_stem)}});

  // --- registration: the back scan into the palm frame, merged cloud ---
  const StageTimer t_reg;
  const Registration reg =
      register_scans(back, palm, in.back_stem + ".png", in.palm_stem + ".png", registration_options(in.options),
                     in.markers_path.empty() ? nullptr : &hints,
                     [&](const std::string& m) { progress("registration: " + m); });
  for (const auto& w : reg.warnings) progress("warning: " + w);
  const Json& rr = reg.report;
  stages.push_back({{"name", "registration"},
                    {"seconds", t_reg.seconds()},
                    {"status", rr["status"]},
                    {"warnings", rr["warnings"]},
                    {"method", rr["method"]},
                    {"marker_radius_mm", {{"value", reg.marker_radius_mm},
                                          {"source", rr["marker_radius"]["source"]}}},
                    {"markers_found", {{"back", rr["scans"]["back"]["markers"].size()},
                                       {"palm", rr["scans"]["palm"]["markers"].size()}}},
                    {"markers_matched", rr["matching"]["pairs_back_palm"].size()},
                    {"marker_only_rms_mm", rr["marker_only"]["rms_mm"]},
                    {"refined_rms_mm", rr["refined"]["rms_mm"]},
                    {"sphere_rms_mm", {{"marker_only", rr["marker_only"]["sphere_rms_mm"]},
                                       {"refined", rr["refined"]["sphere_rms_mm"]}}},
                    {"icp_overlap_fraction", rr["refined"]["icp"]["overlap_fraction"]},
                    {"merged_points", rr["merged"]["points"]},
                    {"timings_ms", rr["timings_ms"]}});

  // --- write: the two clouds in their scanner frames ---
  progress("write: point clouds");
  const StageTimer t_write;
  ensure_directory(in.out_dir);
  namespace fs = std::filesystem;
  const std::string back_ply = (fs::path(in.out_dir) / "back.ply").string();
  const std::string palm_ply = (fs::path(in.out_dir) / "palm.ply").string();
  save_cloud(back_ply, *back_cloud);
  save_cloud(palm_ply, *palm_cloud);
  const std::string reg_json = (fs::path(in.out_dir) / "registration.json").string();
  const std::string merged_ply = (fs::path(in.out_dir) / "merged.ply").string();
  save_json(reg_json, reg.report);
  save_merged(merged_ply, *reg.merged);
  const std::string merged_png = (fs::path(in.out_dir) / "merged.png").string();
  MergedArrays merged = merged_arrays(*reg.merged);  // for the preview and the skin
  write_file_atomic(merged_png, merged_preview_png(merged, reg.markers_palm));
  stages.push_back({{"name", "write"}, {"seconds", t_write.seconds()}});

  // --- skin: strips from the merged cloud, closed into one mesh (docs/skin.md) ---
  SkinStageInputs si;
  si.points = std::move(merged.points);
  si.normals = std::move(merged.normals);
  si.sides = std::move(merged.sides);
  si.rig = rig;
  si.auto_rig = in.auto_rig;
  si.out_dir = in.out_dir;
  si.truth = std::move(truth);
  const Json skin = run_skin_stage(si, in.options, [&](const std::string& m) { progress("skin: " + m); });
  stages.push_back(skin);

  report["stages"] = stages;
  report["outputs"] = {{"back_cloud", back_ply}, {"palm_cloud", palm_ply}, {"registration", reg_json},
                       {"merged_cloud", merged_ply}, {"merged_preview", merged_png}};
  for (const auto& [k, v] : skin["outputs"].items()) report["outputs"][k] = v;
  report["total_seconds"] = total.seconds();
  RunResult r;
  r.report_path = (fs::path(in.out_dir) / "report.json").string();
  save_json(r.report_path, report);
  r.report = report;
  return r;
}

}  // namespace handskin
