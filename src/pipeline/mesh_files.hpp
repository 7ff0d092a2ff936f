#pragma once
/// Every mesh the project writes, read back as one `Mesh` (what `render`, `convert` and the
/// Python module's read_mesh take): PLY, OFF, STL and OBJ through OpenMesh (mesh/), a
/// skin.glb (or a posed .glb) through its glTF reader (rigging/), and patches.obj's free-form
/// bicubic Bézier surfaces tessellated.
#include <string>

#include "mesh/mesh.hpp"

namespace handskin {

/// Tessellation of each free-form patch of an OBJ: kPatchGrid × kPatchGrid quads.
constexpr int kPatchGrid = 12;

/// By extension (.glb; .obj with `surf` statements; else load_mesh). InputError naming the
/// file when it cannot be read or holds no faces.
Mesh read_any_mesh(const std::string& path);

/// The mesh output formats by extension: .ply (binary), .obj, .off, .stl (binary, for
/// printing). UsageError naming `flag` for any other.
void require_mesh_extension(const std::string& path, const std::string& flag);

}  // namespace handskin
