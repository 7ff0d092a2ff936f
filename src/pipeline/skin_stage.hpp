#pragma once
/// The skin stage, shared by `handskin run` and `handskin skin`: the skeleton (given or placed
/// in the cloud), the strip skin, and its quality figures — computed by `run_skin_stage`
/// (no files), turned into the report by `to_json`, its picture rendered by `skin_preview_png`,
/// written by `write_skin_outputs`.
#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/json_util.hpp"
#include "core/output_set.hpp"
#include "core/rig.hpp"
#include "core/texture_map.hpp"
#include "mesh/mesh_distance.hpp"
#include "mesh/mesh.hpp"
#include "pipeline/options.hpp"
#include "skin/auto_rig.hpp"
#include "skin/baseline.hpp"
#include "skin/skin_mesh.hpp"
#include "skin/slices.hpp"
#include "scan/truth_io.hpp"

namespace handskin {

/// slices.json (`handskin-slices/1`, docs/formats.md): the sections the skin was built from.
Json slicing_to_json(const Slicing& s);

/// A rig for the skin stage: a hand-rig/1 file whose joints are in the palm frame (the
/// merged cloud's); another frame is an InputError naming the file.
Rig load_palm_rig(const std::string& path);

/// The rig's back-of-hand direction made to agree with the scans. Without `palm_normal` the
/// direction comes from the joints (x × (index MCP − little MCP)), which points into the palm
/// for a left hand; a planar skeleton cannot tell a left hand back up from a right hand palm
/// up. The merged cloud can: the back scan's points (sides 1) lie out of the back. The rig gets
/// the normal the data say (a rig's own `palm_normal` that points into the palm is turned).
/// Returns a note saying what was done (empty when the rig already agreed), or nothing when
/// the cloud cannot tell (one side only).
std::optional<std::string> orient_rig_to_cloud(Rig* rig, const std::vector<Eigen::Vector3d>& points,
                                               const std::vector<std::uint32_t>& sides);

struct SkinStageInputs {
  std::vector<Eigen::Vector3d> points, normals;  ///< merged cloud, palm frame (markers removed)
  std::vector<std::uint32_t> sides;               ///< per point: 0 palm scan, 1 back scan
  /// A cloud's sheets (sheet_labels), for the skeleton's second placement; empty: `sides`
  /// are the scans' own sheets.
  std::vector<std::uint32_t> sheets;
  std::string cloud_name = "merged cloud";        ///< names the cloud in errors (its file, when read from one)
  std::optional<Rig> rig;                         ///< joints in the palm frame; none: placed automatically
  std::string rig_name = "rig";                   ///< names the given rig in errors (its file)
  bool auto_rig = false;                          ///< place the skeleton even when a rig is given (and compare)
  bool baseline = false;                          ///< also the CGAL Poisson baseline, for comparison
  bool slices = true;                             ///< also the thesis's sections (slices.json)
  std::optional<TruthSkin> truth;                 ///< a synthetic pair's true skin: figures against it
  /// With a rig given (and no --auto-rig), the caller's work run beside the build's first
  /// steps with the stage's own (build_skin's `beside`): run once, on the stage's second
  /// thread, also when the build fails (not when the stage stops before the build: the rig's
  /// orientation refused). Ignored (not run) when the skeleton is placed automatically: the
  /// caller runs it itself then.
  std::function<void()> beside_build;
};

/// The cloud → skin figures take at most this many of the cloud's points, every k-th
/// (distances from the whole cloud would cost more than building the skin).
constexpr size_t kCloudToSkinPoints = 20000;

/// A given rig whose joints lie farther than this (mean) from the skeleton placed in the
/// cloud is refused: the placement is within ~6 mm on every hand of the family
/// (docs/skin.md), a rig of another hand or with its digits swapped is tens of mm off.
constexpr double kRigRefuseMm = 20.0;
/// ... and one farther than this is reported with a warning.
constexpr double kRigWarnMm = 8.0;

struct SkinTruthFigures {
  std::string skin_path;
  double exclude_mm = 0;
  OneWayDistance skin_to_truth, truth_to_skin;
  double seconds = 0;  ///< the comparison's own time (in the stage's; a run without a truth has none)
  std::optional<OneWayDistance> baseline_to_truth, truth_to_baseline;
};

struct SkinBaseline {
  BaselineResult result;
  MeshHealth health;
  OneWayDistance cloud_to_baseline;
};

struct SkinStageResult {
  SkinResult skin;                        ///< the mesh, its tubes, ring grid, health, timings
  Rig rig;                                ///< the rig the skin was built on
  bool automatic = false;                 ///< that rig was placed in the cloud
  std::optional<AutoRig> placed;          ///< the automatic placement, when it ran and succeeded
  std::string placement_failed;           ///< why it failed (a given rig was then used unchecked)
  double placement_seconds = 0;
  std::optional<JointError> against_given;  ///< the placement against the given rig
  std::string rig_orientation;            ///< what orient_rig_to_cloud did to the given rig
  std::vector<std::string> warnings;
  double build_seconds = 0, seconds = 0;  ///< the skin build; the whole stage
  OneWayDistance cloud_to_skin;
  std::optional<Slicing> slices;          ///< the thesis's sections (slices.json)
  std::optional<SkinBaseline> baseline;
  std::optional<SkinTruthFigures> truth;
};

/// Place the skeleton when asked (or when no rig is given), build the skin and measure it.
/// Writes nothing. Throws InputError naming the rig or the cloud when the rig does not fit
/// (or lies more than kRigRefuseMm from the placed skeleton), or when the skin would not be a
/// closed, manifold, outward, self-intersection-free surface.
SkinStageResult run_skin_stage(const SkinStageInputs& in, const PipelineOptions& options,
                               const std::function<void(const std::string&)>& progress);

/// The report's "skin" stage (no output paths).
Json to_json(const SkinStageResult& r);

/// Every output name the skin stage can write.
const std::vector<std::string>& skin_output_names();
/// The names it writes: with the skeleton placed automatically (rig_auto.json), the
/// sections (slices.json), the Poisson baseline (baseline.ply).
std::vector<std::string> skin_output_plan(bool automatic, bool slices, bool baseline);

/// skin.png: the skin from the back, fingers to the right; with `texture` (a map of
/// r.skin.mesh) showing it, blended by `texture_weight`.
std::string skin_preview_png(const SkinStageResult& r, const TextureMap* texture = nullptr, float texture_weight = 0.7f);

/// Stage skin.ply (labels), skin.obj (with vertex normals; with `texture`, its coordinates
/// and skin.mtl, whose map is texture.png, which the caller writes beside it), skin.png
/// (`skin_png`, rendered by the caller), and as computed rig_auto.json, slices.json,
/// baseline.ply into `out`. Returns {key: final path} for the report's "outputs".
/// `ply_staged` (if given) is called once skin.ply is staged, before the other files: the
/// run's gates read it back beside their writing.
Json write_skin_outputs(OutputSet& out, const SkinStageResult& r, const std::string& skin_png,
                        const TextureMap* texture = nullptr, const std::function<void()>& ply_staged = {});

}  // namespace handskin
