#pragma once
/// skin_grid.json (`handskin-skin-grid/1`, docs/formats.md): what the patch layout needs of a
/// skin beyond skin.ply — each tube's ring grid before stitching, whether it is present, its
/// section radius, and the finger webs — so that `handskin patches` fits the folder's own
/// skin instead of building it again. Written by the skin stage's writer; read here.
#include <optional>
#include <string>

#include "core/json_util.hpp"
#include "core/rig.hpp"
#include "skin/skin_mesh.hpp"

namespace handskin {

/// The file's JSON: the rig's joints the skin was built on, the webs, and per tube (SkinTube
/// order) its present flag, section radius, stations, rings and pole. Numbers keep every bit
/// (shortest round-trip form).
Json skin_grid_to_json(const SkinResult& skin, const Rig& rig);

/// The skin of a run folder as the patch stage needs it: skin.ply's mesh (`skin_ply`) with
/// the grid, tubes and webs of `grid_json`, and the bones of `rig`; nullopt when `rig`'s
/// joints are not those the skin was built on (beyond 1e-6 mm). Throws InputError naming the
/// file and key when either file is malformed.
std::optional<SkinResult> read_folder_skin(const std::string& skin_ply, const std::string& grid_json, const Rig& rig);

}  // namespace handskin
