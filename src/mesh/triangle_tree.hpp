#pragma once
/// Internal to the synth library: triangles from a vertex/face list in a CGAL AABB tree, for
/// ray casting (the scanner, marker placement) and distance queries (MeshDistance).
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <Eigen/Core>
#include <array>
#include <vector>

namespace handskin::cgal {

using K = CGAL::Simple_cartesian<double>;
using Triangle = K::Triangle_3;
using TriIter = std::vector<Triangle>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<K, TriIter>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;

inline K::Point_3 point(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

/// The triangles and a tree over them (the tree refers into `triangles`, so the two live together).
struct TriangleTree {
  std::vector<Triangle> triangles;
  Tree tree;
  TriangleTree(const std::vector<Eigen::Vector3d>& v, const std::vector<std::array<int, 3>>& f) {
    triangles.reserve(f.size());
    for (const auto& t : f) triangles.emplace_back(point(v[t[0]]), point(v[t[1]]), point(v[t[2]]));
    tree.insert(triangles.begin(), triangles.end());
    tree.build();
  }
  TriangleTree(const TriangleTree&) = delete;
  TriangleTree& operator=(const TriangleTree&) = delete;
};

}  // namespace handskin::cgal
