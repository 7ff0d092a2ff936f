#pragma once
/// The skin stage (issue 5), shared by `handskin run` and `handskin skin`: the strip skin from
/// the merged cloud and the rig, its files, and its figures for the report.
#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/json_util.hpp"
#include "core/rig.hpp"
#include "mesh/trimesh.hpp"
#include "pipeline/options.hpp"

namespace handskin {

/// The true skin of a synthetic pair (truth.json, `handskin-truth/1`, written by `synth scan`).
struct TruthSkin {
  std::string path;                     ///< the truth.json
  Json json;                            ///< all of it (the registration command reads back_to_palm)
  std::string skin_path;                ///< its "skin" mesh, relative to the truth.json
  TriMesh skin;
  std::vector<Eigen::Vector3d> markers;  ///< "markers_palm": marker centres, palm frame
  double exclude_mm = 7;                 ///< samples this near a marker's centre are left out (radius + 3)
};
/// Read and check a truth.json and its skin mesh; throws InputError naming the file and key.
/// Callers read it before any work, so a bad file fails early and nothing is half-written.
TruthSkin load_truth_skin(const std::string& path);

/// A rig for the skin stage: a hand-rig/1 file whose joints are in the palm frame (the
/// merged cloud's); another frame is an InputError naming the file.
Rig load_palm_rig(const std::string& path);

struct SkinStageInputs {
  std::vector<Eigen::Vector3d> points, normals;  ///< merged cloud, palm frame (markers removed)
  std::vector<std::uint32_t> sides;               ///< per point: 0 palm scan, 1 back scan
  std::optional<Rig> rig;                         ///< joints in the palm frame; none: placed automatically
  bool auto_rig = false;                          ///< place the skeleton even when a rig is given (and compare)
  std::string out_dir;
  std::optional<TruthSkin> truth;  ///< a synthetic pair's true skin: figures against it
};

/// Place the skeleton when asked (or when no rig is given: rig_auto.json), build the skin and
/// write skin.ply (labels), skin.obj, skin.png, and as configured slices.json and baseline.ply. Returns the stage's figures (the report's "skin" stage) with
/// the output paths under "outputs". Throws InputError (nothing of this stage written) when
/// the skin cannot be built or would not be a closed, manifold, self-intersection-free surface.
Json run_skin_stage(const SkinStageInputs& in, const PipelineOptions& options,
                    const std::function<void(const std::string&)>& progress);

}  // namespace handskin
