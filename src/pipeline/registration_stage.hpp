#pragma once
/// The registration stage's outputs (registration.json, merged.ply, merged.png), shared by
/// `handskin run` and `handskin register`, and its figures against a synthetic pair's truth.
#include <string>
#include <vector>

#include "core/json_util.hpp"
#include "core/output_set.hpp"
#include "register/registration.hpp"
#include "scan/truth_io.hpp"

namespace handskin {

/// A side view of the merged cloud (palm samples blue-grey, back samples skin-toned, the
/// markers as red dots): how the two halves meet, at a glance. PNG bytes.
std::string merged_preview_png(const MergedArrays& merged, const std::vector<Eigen::Vector3d>& markers, int width = 1000);

/// The marker-only and the chosen transform against the true one, over the true skin:
/// {"marker_only": {rotation_deg, skin_mean_mm, skin_max_mm}, "chosen": {...}, "file": ...}.
Json registration_against_truth(const Registration& reg, const TruthSkin& truth);

/// registration.json (handskin-registration/1, docs/formats.md): every detail of the
/// registration, from its typed result.
Json registration_to_json(const Registration& reg);

/// The registration's figures for a run report's "registration" stage (typed figures → JSON).
Json registration_summary_json(const Registration& reg);

/// Every output name the registration stage writes (for OutputSet::retire).
const std::vector<std::string>& registration_output_names();

/// merged.png: merged_preview_png of the registration's merged cloud and markers.
std::string merged_preview_png(const Registration& reg);

/// Stage registration.json (`report`: the registration's, with anything the caller added),
/// merged.ply and merged.png (`merged_png`, rendered by the caller) into `out`. Returns
/// {key: final path}.
Json write_registration_outputs(OutputSet& out, const Registration& reg, const Json& report,
                                const std::string& merged_png);

}  // namespace handskin
