#pragma once
/// `handskin-truth/1` (truth.json, docs/formats.md): what `synth scan` knows about a pair it
/// made — the true back→palm transform, the markers, the true skin — written beside the
/// scans. Its reader, which `register`, `skin` and `run --truth` use to measure themselves,
/// is scan/truth_io.hpp.
#include <cstdint>
#include <string>

#include "core/json_util.hpp"
#include "synth/replica.hpp"

namespace handskin {

/// truth.json for `pair`, made with `seed` and these options; its "skin" names `skin_file`
/// (relative to the truth.json, written beside it).
Json truth_to_json(const ScanPair& pair, const Rig& hand_rig, std::uint64_t seed, const ReplicaOptions& replica,
                   const ScannerOptions& scanner, const std::string& skin_file = "truth_skin.ply");

}  // namespace handskin
