#pragma once
/// A CGAL Surface_mesh (triangles) as the pipeline's OpenMesh TriMesh. Header-only, for the
/// libraries that build meshes with CGAL (the hand mesher, the skin baseline); the mesh
/// library's public headers stay free of CGAL (its distances use CGAL inside the .cpp).
#include <CGAL/Surface_mesh.h>
#include <CGAL/boost/graph/iterator.h>

#include <vector>

#include "core/errors.hpp"
#include "mesh/trimesh.hpp"

namespace handskin {

template <class Point>
TriMesh to_trimesh(const CGAL::Surface_mesh<Point>& sm) {
  TriMesh mesh;
  // Indexed by the vertices' indices, which run past number_of_vertices() while removed
  // vertices await garbage collection.
  std::vector<TriMesh::VertexHandle> vh(sm.number_of_vertices() + sm.number_of_removed_vertices());
  for (auto v : sm.vertices()) {
    const Point& p = sm.point(v);
    vh[v.idx()] = mesh.add_vertex(TriMesh::Point(p.x(), p.y(), p.z()));
  }
  for (auto f : sm.faces()) {
    std::vector<TriMesh::VertexHandle> tri;
    for (auto v : CGAL::vertices_around_face(sm.halfedge(f), sm)) tri.push_back(vh[v.idx()]);
    HS_CHECK(tri.size() == 3, "a CGAL mesh face is not a triangle");
    mesh.add_face(tri);
  }
  return mesh;
}

}  // namespace handskin
