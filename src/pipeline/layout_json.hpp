#pragma once
/// A patch layout as JSON: the "layout" of patches.json (`handskin-patches/1`) and the
/// layout file `handskin-patch-layout/1` (docs/formats.md), both ways.
#include <string>

#include "core/json_util.hpp"
#include "patches/layout.hpp"

namespace handskin {

/// `{"vertices": [[x, y, z]…], "faces": [[a, b, c, d]…], "names": […], "creases": [[a, b]…]}`.
Json layout_to_json(const PatchLayout& layout);
/// The inverse; every error names `file` and the entry. The layout must be closed (checked).
PatchLayout layout_from_json(const Json& j, const std::string& file);

/// The layout of a patches file (`handskin-patches/1`, its "layout") or of a layout file
/// (`handskin-patch-layout/1`, the same key). Throws InputError naming `file` and the entry.
PatchLayout parse_patch_layout(const Json& j, const std::string& file);

}  // namespace handskin
