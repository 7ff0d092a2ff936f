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
#include "pipeline/options.hpp"

namespace handskin {

struct SkinStageInputs {
  std::vector<Eigen::Vector3d> points, normals;  ///< merged cloud, palm frame (markers removed)
  std::vector<std::uint32_t> sides;               ///< per point: 0 palm scan, 1 back scan
  std::optional<Rig> rig;                         ///< joints in the palm frame; none: placed automatically
  bool auto_rig = false;                          ///< place the skeleton even when a rig is given (and compare)
  std::string out_dir;
  std::string truth_path;  ///< optional truth.json of a synthetic pair: figures against its skin
};

/// Place the skeleton when asked (or when no rig is given: rig_auto.json), build the skin and
/// write skin.ply (labels), skin.obj, skin.png, and as configured slices.json and baseline.ply. Returns the stage's figures (the report's "skin" stage) with
/// the output paths under "outputs". Throws InputError (nothing of this stage written) when
/// the skin cannot be built or would not be a closed, manifold, self-intersection-free surface.
Json run_skin_stage(const SkinStageInputs& in, const PipelineOptions& options,
                    const std::function<void(const std::string&)>& progress);

}  // namespace handskin
