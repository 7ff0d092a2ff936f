#pragma once
/// OpenMesh's triangle mesh, for mesh/'s own files: the readers and writers, and the checks
/// that need half-edge topology. Stages exchange `Mesh` (mesh/mesh.hpp), not this.
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>

#include "mesh/mesh.hpp"

namespace handskin {

struct MeshTraits : public OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;
  using Normal = OpenMesh::Vec3d;
};
using TriMesh = OpenMesh::TriMesh_ArrayKernelT<MeshTraits>;

/// The faces in OpenMesh's order, each from its halfedge (for a face added as (a, b, c): a, b, c).
Mesh from_trimesh(const TriMesh& mesh);
/// Vertices in order; faces added in order (those OpenMesh cannot add are left out).
TriMesh to_trimesh(const Mesh& mesh, size_t* dropped = nullptr);
/// Health of the half-edge structure as it is.
MeshHealth trimesh_health(const TriMesh& mesh);

}  // namespace handskin
