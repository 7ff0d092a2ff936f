#pragma once
/// Meshing the implicit default hand with CGAL's surface mesher.
#include <string>

#include "mesh/mesh.hpp"
#include "synth/hand_model.hpp"

namespace handskin {

struct HandMeshOptions {
  double facet_angle_deg = 25.0;   ///< lower bound on triangle angles
  double facet_size_mm = 1.6;      ///< upper bound on the Delaunay ball radius of a facet
  double facet_distance_mm = 0.04; ///< upper bound on facet-centre to surface distance
  unsigned seed = 1;               ///< CGAL's random (initial points) is reseeded with this
  bool IsValid(std::string* error) const;
};

struct HandMeshResult {
  Mesh mesh;        ///< closed, 2-manifold, outward-oriented, in the hand frame (mm)
  MeshHealth health;
  bool self_intersects = false;
  double seconds = 0;
};

/// [CGAL Surface_mesher, make_surface_mesh with Manifold_tag] over HandModel::value.
/// Throws InternalError if the result is not a closed manifold (a mesher or model bug).
HandMeshResult mesh_hand(const HandModel& model, const HandMeshOptions& options);

}  // namespace handskin
