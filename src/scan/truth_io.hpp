#pragma once
/// Reading `handskin-truth/1` (truth.json, docs/formats.md): what `synth scan` knows about a
/// pair it made — the true back→palm transform, the markers, the true skin. `register`,
/// `skin`, `patches` and `run --truth` read it to measure themselves; the generator that
/// writes it is synth/truth.hpp.
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "mesh/mesh.hpp"

namespace handskin {

/// A truth.json read back, with its true skin.
struct TruthSkin {
  std::string path;                      ///< the truth.json
  Eigen::Isometry3d back_to_palm = Eigen::Isometry3d::Identity();
  std::string skin_path;                 ///< its "skin" mesh, relative to the truth.json
  Mesh skin;
  std::vector<Eigen::Vector3d> markers;  ///< "markers_palm": marker centres, palm frame
  double exclude_mm = 7;                 ///< samples this near a marker's centre are left out (radius + 3)
};
/// Read and check a truth.json and its skin mesh; throws InputError naming the file and key.
/// Callers read it before any work, so a bad file fails early and nothing is half-written.
TruthSkin load_truth_skin(const std::string& path);

}  // namespace handskin
