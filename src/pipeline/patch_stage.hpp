#pragma once
/// The patch stage (issue 13): bicubic Bézier patches fitted on the skin's ring grid and the
/// merged cloud, their figures, and their files (patches.json, patches.obj, patches.ply,
/// patches.step, report.html). `handskin patches` and `run` run it.
#include <optional>
#include <string>
#include <vector>

#include "core/json_util.hpp"
#include "core/output_set.hpp"
#include "mesh/mesh_distance.hpp"
#include "core/rig.hpp"
#include "export/step.hpp"
#include "patches/patches.hpp"
#include "scan/truth_io.hpp"

namespace handskin {

/// A picture with its caption for the report page (e.g. the rigged skin in a posture), PNG.
struct ReportPicture {
  std::string caption, png;
};

struct PatchReportFigures {
  /// Table 4.1 computed the thesis's way: every patch sampled on error_grid × error_grid
  /// points, each data point's distance to the nearest sample; per side (palm, back).
  int error_grid = 100;
  std::array<double, 2> cell_mean_mm{}, cell_max_mm{};
  /// The scanner's noise floor per side: RMS distance of the points to planes fitted to their
  /// neighbours within 1.5 mm (of the same scan), over a sample of the points.
  std::array<double, 2> noise_floor_mm{};
  double seconds = 0;
};

/// report.html's pictures (PNG), rendered in the stage: the data coloured by its distance to
/// the surface seen from the palm (palm scan) and from the back (back scan), empty when a side
/// has no points; the patch layout from the back and from the palm.
struct PatchReportPictures {
  std::string palm_error, back_error, layout_back, layout_palm;
};

/// Table 4.1's cell-grid error and the noise floor (for the report).
PatchReportFigures patch_report_figures(const PatchSkin& s, int error_grid);
/// The report's pictures of the fit, in the views of `rig`'s hand frame.
PatchReportPictures patch_report_pictures(const PatchSkin& s, const Rig& rig);
Json to_json(const PatchReportFigures& f);

/// What the command and the run say when the hand's layout was fitted more than once (its
/// patches strayed from the polygon skin: PatchSkin::layout_tries), else nothing.
std::optional<std::string> layout_note(const PatchSkin& s);
/// What the fit did when two fingers' tubes passed through each other (PatchSkin::separations), or nothing.
std::optional<std::string> separation_note(const PatchSkin& s);
/// Why the fit kept has a raised fairness (PatchSkin::fairness_used), when it has.
std::optional<std::string> fairness_note(const PatchSkin& s);

struct PatchStageResult {
  PatchSkin patches;
  PatchOptions options;
  Mesh tessellation;                        ///< patches.ply
  std::optional<OneWayDistance> surface_to_truth, truth_to_surface;
  /// The patches against the polygon skin they were laid on (samples every 4 mm², no truth
  /// needed): where they stray from it, a patch bridges what the skin follows.
  OneWayDistance surface_to_skin;
  PatchCrossings crossings;  ///< patches.ply passing through itself
  std::string truth_file;
  double truth_seconds = 0;  ///< the comparison with the truth (in `seconds`; none without a truth)
  PatchReportFigures figures;
  PatchReportPictures pictures;
  /// patches.step with its shape read back; made by the writer when absent (`run` makes it
  /// beside its pictures).
  std::optional<StepFile> step;
  double seconds = 0;
};

/// Fit the patches, tessellate them, and with a truth measure the surface against it; with
/// `pictures`, also the report's pictures (else the caller makes them with
/// patch_report_pictures, e.g. beside other work: `run` does).
PatchStageResult run_patch_stage(const SkinResult& skin, const Rig& rig, const std::vector<Eigen::Vector3d>& points,
                                 const std::vector<std::uint32_t>& sides, const PatchOptions& options,
                                 const TruthSkin* truth, int error_grid = 100, bool pictures = true);

/// The stage's figures (report.json's body).
Json to_json(const PatchStageResult& r);

/// `handskin-patches/1`: every patch's 16 control points (row-major P00…P33, the first index
/// around the tube), its tube, spans, link and fit, and each control point's link.
Json patches_to_json(const PatchSkin& s);

/// OBJ free-form surfaces: each tube's net as shared vertices, each patch a `cstype bezier`,
/// `deg 3 3` surface over them.
std::string patches_obj(const PatchSkin& s);

/// Stage patches.json, patches.obj, patches.ply, patches.step and report.html (`run_report`
/// adds the run's stages and gates to it) into `out`; returns {key: final path}. Serialises
/// only: the pictures were rendered by the stage (and the STEP file made, when r.step holds
/// it; else here). `step` (if given) receives the STEP file's shape as OCCT reads it back from
/// the bytes written (faces, shells, closed, the box).
Json write_patch_outputs(OutputSet& out, const PatchStageResult& r, const Json& run_report = Json(),
                         const std::vector<ReportPicture>& posed = {}, Json* step = nullptr);
/// The two halves of write_patch_outputs: the surface's files (patches.json, .obj, .ply,
/// .step; `step` as there), then report.html.
Json write_patch_files(OutputSet& out, const PatchStageResult& r, Json* step = nullptr);
Json write_patch_report(OutputSet& out, const PatchStageResult& r, const Json& run_report,
                        const std::vector<ReportPicture>& posed = {});
const std::vector<std::string>& patch_output_names();

}  // namespace handskin
