#pragma once
/// A CGAL Surface_mesh (triangles) as the `Mesh` that stages exchange. Header-only, for the
/// libraries that build meshes with CGAL (the hand mesher, the skin, the sawn replica); the
/// mesh library's public headers stay free of CGAL (its distances use CGAL inside the .cpp).
#include <CGAL/Surface_mesh.h>
#include <CGAL/boost/graph/iterator.h>

#include <vector>

#include "core/errors.hpp"
#include "mesh/mesh.hpp"

namespace handskin {

/// Vertices in the order of sm.vertices(), renumbered from 0; each face's corners from its
/// halfedge, as CGAL::vertices_around_face gives them.
template <class Point>
Mesh to_mesh(const CGAL::Surface_mesh<Point>& sm) {
  Mesh mesh;
  // Indexed by the vertices' indices, which run past number_of_vertices() while removed
  // vertices await garbage collection.
  std::vector<int> id(sm.number_of_vertices() + sm.number_of_removed_vertices(), -1);
  mesh.vertices.reserve(sm.number_of_vertices());
  for (auto v : sm.vertices()) {
    const Point& p = sm.point(v);
    id[v.idx()] = static_cast<int>(mesh.vertices.size());
    mesh.vertices.emplace_back(CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z()));
  }
  mesh.faces.reserve(sm.number_of_faces());
  for (auto f : sm.faces()) {
    std::array<int, 3> tri{};
    int k = 0;
    for (auto v : CGAL::vertices_around_face(sm.halfedge(f), sm)) {
      HS_CHECK(k < 3, "a CGAL mesh face is not a triangle");
      tri[k++] = id[v.idx()];
    }
    HS_CHECK(k == 3, "a CGAL mesh face is not a triangle");
    mesh.faces.push_back(tri);
  }
  return mesh;
}

}  // namespace handskin
