#pragma once
/// `handskin run`: the whole pipeline from two scans, or a cloud from any scanner (and a rig,
/// or none) to the skin.
/// Stages: ingest (both scans read and checked, to point clouds), registration (the back scan
/// into the palm frame, merged cloud), skin (skeleton, strips, closed mesh, figures), patches
/// (bicubic Bézier patches on the skin's ring grid, their fitting error), rigging (the skin
/// bound to the skeleton), texture (the skin's colour from the scans' photos, when there are).
/// `run_pipeline` computes every stage and writes nothing; `write_run_outputs` stages every
/// file into an OutputSet, which the caller commits — so a failure anywhere leaves the
/// output folder exactly as it was (docs/architecture.md).
#include <functional>
#include <optional>
#include <string>

#include "core/json_util.hpp"
#include "core/output_set.hpp"
#include "pipeline/cloud_stage.hpp"
#include "pipeline/gates.hpp"
#include "pipeline/options.hpp"
#include "pipeline/patch_stage.hpp"
#include "rigging/gltf.hpp"
#include "texture/texture.hpp"
#include "pipeline/skin_stage.hpp"
#include "register/registration.hpp"
#include "scan/cloud.hpp"
#include "scan/cubist_io.hpp"

namespace handskin {

struct RunInputs {
  std::string back_stem;   ///< `<stem>.png` + `<stem>.json`, side "back"
  std::string palm_stem;   ///< side "palm"
  /// Instead of the two scans: a cloud from any scanner (docs/clouds.md), its units, and
  /// which hand it is when the fingers' bend cannot tell.
  std::vector<std::string> clouds;
  LengthUnit units = LengthUnit::Millimetre;
  std::optional<HandSide> hand;
  std::string rig_path;    ///< hand-rig/1, palm frame; empty: the skeleton is placed automatically
  bool auto_rig = false;   ///< place the skeleton automatically even with a rig (and compare)
  bool baseline = false;   ///< also the CGAL Poisson baseline (or the pipeline's skin.baseline)
  /// Also back.ply and palm.ply: each scan's measured points in its own scanner frame. On
  /// request only (issue 39): 6 MB a run that repeat the input scans (`convert` makes them too).
  bool scan_clouds = false;
  std::string markers_path;   ///< optional handskin-markers/1 (manual marker positions)
  std::string pipeline_path;  ///< empty: built-in defaults (= pipelines/cubist.json)
  std::string truth_path;     ///< optional truth.json (synthetic pairs): errors against it in the report
  std::string posture_model = "builtin:anatomical";  ///< the posture model skin.glb carries
  /// The scans' photos for the texture; empty: `<stem>.photo.png` when both exist (else no
  /// texture). A photo given here must exist. A cloud has no photos, hence no texture.
  std::string back_photo, palm_photo;
  PipelineOptions options;
};

using ProgressFn = std::function<void(const std::string&)>;

struct ScanFigures {
  std::string stem;
  ScanSide side = ScanSide::Back;
  int scanlines = 0, points = 0;
  size_t returns = 0;
};

/// Everything `run` computed: each stage's result with its figures and timings.
struct RunResult {
  RunInputs inputs;
  ScanFigures back, palm;
  Cloud::Ptr back_cloud, palm_cloud;  ///< the scans as point clouds, scanner frames
  /// run --cloud: the cloud stage, which stands for ingest and registration (no scans, no
  /// registration: back_cloud, palm_cloud and registration stay empty).
  std::optional<CloudStageResult> cloud;
  double ingest_seconds = 0, registration_seconds = 0;
  Registration registration;
  std::optional<Json> registration_truth;  ///< registration_against_truth, with --truth
  SkinStageResult skin;
  std::optional<PatchStageResult> patches;  ///< Bézier patches on the skin's ring grid (patches.enabled)
  std::optional<SkinTexture> texture;  ///< the bake's figures; its map is moved into rigged.texture
  std::string texture_note;      ///< why there is no texture, when there is none
  RiggedSkin rigged;             ///< the skin bound to the skeleton, with the posture model (skin.glb)
  std::vector<ReportPicture> posed;  ///< the rigged skin in a few postures, for report.html
  std::string merged_png, skin_png;  ///< merged.png and skin.png, rendered
  std::string glb;                   ///< skin.glb's bytes
  double rigging_seconds = 0;
  /// The pictures (skin.png, the posed skins, the patches' pictures), skin.glb and the wait for
  /// patches.step, after the texture: a stage of its own in report.json, so that the stages'
  /// seconds add up to the run's. `step_seconds`: patches.step's own making (sewing, writing,
  /// reading back), on a thread of its own from the end of the patch stage.
  double pictures_seconds = 0, step_seconds = 0;
  double seconds = 0;  ///< all stages, before any output is written
};

/// Run every stage. Reads the inputs, writes nothing. Bad input throws InputError naming it.
RunResult run_pipeline(const RunInputs& in, const ProgressFn& progress);

/// Every output name `run` can write (an earlier run's outputs this one does not make go).
std::vector<std::string> run_output_names();
/// The outputs `run` will write with these inputs (their options read): what
/// OutputSet::claim checks before any work.
std::vector<std::string> run_output_plan(const RunInputs& in);

/// The two photos the texture is baked from: given, or `<stem>.photo.png` beside both scans;
/// none when texture.enabled is false or they are not both there (`note` says why).
std::optional<std::pair<std::string, std::string>> run_photo_paths(const RunInputs& in, std::string* note = nullptr);

struct RunWritten {
  Json report;         ///< report.json as staged (handskin-report/1)
  QualityGates gates;  ///< measured on the staged files (also in the report)
};

/// Stage every output of `r` into `out` — back.ply, palm.ply, the registration's, the skin's,
/// and report.json last — with the quality gates measured on the staged files (skin.ply read
/// back). The caller commits (or, with --strict and a failed gate, does not).
RunWritten write_run_outputs(OutputSet& out, const RunResult& r);

/// `handskin run` as one call, for every front end (the CLI, the Python module): the output
/// folder claimed before any work (`out_options`: --force, the signal handlers), every stage
/// computed, every output staged, `settle` shown the quality gates measured on the staged
/// files (it may throw — GateFailure under --strict — and then nothing is written), then the
/// commit. Returns the report as written.
RunWritten run_into_folder(const RunInputs& in, const std::string& out_dir, const OutputSetOptions& out_options,
                           const ProgressFn& progress, const std::function<void(const QualityGates&)>& settle);

}  // namespace handskin
