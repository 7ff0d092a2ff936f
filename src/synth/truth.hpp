#pragma once
/// `handskin-truth/1` (truth.json, docs/formats.md): what `synth scan` knows about a pair it
/// made — the true back→palm transform, the markers, the true skin — written beside the
/// scans, and read back by `register`, `skin` and `run --truth` to measure themselves.
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "core/json_util.hpp"
#include "mesh/trimesh.hpp"
#include "synth/replica.hpp"

namespace handskin {

/// truth.json for `pair`, made with `seed` and these options; its "skin" names `skin_file`
/// (relative to the truth.json, written beside it).
Json truth_to_json(const ScanPair& pair, const Rig& hand_rig, std::uint64_t seed, const ReplicaOptions& replica,
                   const ScannerOptions& scanner, const std::string& skin_file = "truth_skin.ply");

/// A truth.json read back, with its true skin.
struct TruthSkin {
  std::string path;                      ///< the truth.json
  Json json;                             ///< all of it
  Eigen::Isometry3d back_to_palm = Eigen::Isometry3d::Identity();
  std::string skin_path;                 ///< its "skin" mesh, relative to the truth.json
  TriMesh skin;
  std::vector<Eigen::Vector3d> markers;  ///< "markers_palm": marker centres, palm frame
  double exclude_mm = 7;                 ///< samples this near a marker's centre are left out (radius + 3)
};
/// Read and check a truth.json and its skin mesh; throws InputError naming the file and key.
/// Callers read it before any work, so a bad file fails early and nothing is half-written.
TruthSkin load_truth_skin(const std::string& path);

}  // namespace handskin
