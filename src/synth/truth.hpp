#pragma once
/// `handskin-truth/1` (truth.json, docs/formats.md): what `synth scan` knows about a pair it
/// made — the true back→palm transform, the markers, the true skin — written beside the
/// scans. Its reader, which `register`, `skin` and `run --truth` use to measure themselves,
/// is scan/truth_io.hpp.
#include <cstdint>
#include <string>

#include "core/json_util.hpp"
#include "synth/cloud_sim.hpp"
#include "synth/replica.hpp"

namespace handskin {

/// truth.json for `pair`, made with `seed` and these options; its "skin" names `skin_file`
/// (relative to the truth.json, written beside it).
Json truth_to_json(const ScanPair& pair, const Rig& hand_rig, std::uint64_t seed, const ReplicaOptions& replica,
                   const ScannerOptions& scanner, const std::string& skin_file = "truth_skin.ply");

/// truth.json for a cloud from simulate_cloud (`synth cloud`): "kind": "cloud", the true skin
/// in the cloud's frame (mm, the merged cloud's = half b's), `back_to_palm` the first half's
/// transform into the second's (identity's place for a merged cloud: it is half b's frame).
Json cloud_truth_to_json(const CloudSim& sim, const Rig& hand_rig, std::uint64_t seed, const CloudSimOptions& options,
                         const std::string& skin_file = "truth_skin.ply");

}  // namespace handskin
