#include <CGAL/Polygon_mesh_processing/compute_normal.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>

#include <Eigen/IterativeLinearSolvers>
#include <algorithm>
#include <cmath>

#include "mesh/point_grid.hpp"
#include "skin/skin_steps.hpp"

namespace handskin::skin_steps {

namespace PMP = CGAL::Polygon_mesh_processing;

// Step 8. The triangles, not the vertices, are fitted: each vertex j moves by t_j along its
// normal n_j, and the t minimise
//   Σ_points (n_f · (Σ_k b_k (v_k + t_k n_k) − q))²  +  λ Σ_edges (t_i − t_j)²  +  μ Σ_j t_j²
// over the cloud's points q (each with its nearest face f and barycentric b there), a few
// rounds with the nearest faces found again. Putting the vertices themselves on the data
// (tried first) leaves every chord inside a convex surface: the skin's mean distance to the
// true skin grew (0.094 → 0.102 mm on H01) while the vertices' fell. The edge term keeps
// the moves smooth (no wrinkle noise: a bump smaller than a triangle is not followed); μ
// keeps a vertex with no points near it where it was. Why by hand: CGAL's and OpenMesh's
// smoothers move vertices toward each other, not toward data; PCL's MLS resamples points and
// does not keep a mesh's vertices. Eigen's conjugate gradients per round (the matrix is sparse,
// symmetric positive definite and diagonally heavy).
DataFit fit_to_data(SM* sm, const std::vector<Eigen::Vector3d>& points, const DataFitOptions& o) {
  DataFit f;
  if (!o.enabled) return f;
  const size_t N = sm->num_vertices();  // indexed by vertex index (a decimated mesh keeps removed ones)
  std::vector<double> total(N, 0.0);
  const size_t stride = std::max<size_t>(1, points.size() / static_cast<size_t>(o.max_points));
  const size_t n_rows = (points.size() + stride - 1) / stride;
  for (int round = 0; round < o.rounds; ++round) {
    auto normals = sm->add_property_map<SM::Vertex_index, K::Vector_3>("v:fit_normal", CGAL::NULL_VECTOR).first;
    PMP::compute_vertex_normals(*sm, normals);
    // The nearest face of a point: the nearest of the faces around its nearest vertex (a
    // uniform grid of the vertices; twice as fast here as CGAL's AABB tree, and a least-squares
    // fit does not care whether a point on a far edge of a fan goes to the neighbouring fan).
    std::vector<Eigen::Vector3d> vpos;
    std::vector<SM::Vertex_index> vid;
    for (const auto v : sm->vertices()) {
      vpos.emplace_back(sm->point(v).x(), sm->point(v).y(), sm->point(v).z());
      vid.push_back(v);
    }
    const PointGrid vgrid(vpos, 3.0);
    const auto project = K().construct_projected_point_3_object();
    struct Row {
      std::array<int, 3> v{-1, -1, -1};
      std::array<double, 3> coef{};
      double r = 0;
    };
    std::vector<Row> rows(n_rows);
    // Each point's row in its own slot: the same rows on any number of threads.
#pragma omp parallel for schedule(static)
    for (long nn = 0; nn < static_cast<long>(rows.size()); ++nn) {
      const size_t n = static_cast<size_t>(nn);
      const Eigen::Vector3d& p = points[n * stride];
      const K::Point_3 q(p.x(), p.y(), p.z());
      // A point within max_move of a face is within max_move and an edge's length (~5 mm
      // after decimation) of that face's corners.
      const int nv = vgrid.nearest(p, o.max_move_mm + 10.0);
      if (nv < 0) continue;
      K::Point_3 c = q;
      SM::Face_index face;
      double best = 1e300;
      for (const auto fc : CGAL::faces_around_target(sm->halfedge(vid[static_cast<size_t>(nv)]), *sm)) {
        if (fc == SM::null_face()) continue;
        const auto h = sm->halfedge(fc);
        const K::Triangle_3 tri(sm->point(sm->source(h)), sm->point(sm->target(h)), sm->point(sm->target(sm->next(h))));
        const K::Point_3 x = project(tri, q);
        const double d2 = CGAL::squared_distance(q, x);
        if (d2 < best) best = d2, c = x, face = fc;
      }
      if (best == 1e300) continue;
      if (CGAL::squared_distance(q, c) > o.max_move_mm * o.max_move_mm) continue;  // not this surface's point
      std::array<SM::Vertex_index, 3> vs;
      int k = 0;
      for (auto v : CGAL::vertices_around_face(sm->halfedge(face), *sm)) vs[k++] = v;
      const K::Point_3 &a = sm->point(vs[0]), &b = sm->point(vs[1]), &cc = sm->point(vs[2]);
      K::Vector_3 nf = CGAL::cross_product(b - a, cc - a);
      const double area2 = std::sqrt(nf.squared_length());
      if (!(area2 > 1e-12)) continue;
      nf = nf / area2;
      // Barycentric coordinates of the closest point (it lies in the triangle).
      const std::array<double, 3> bary = {std::sqrt(CGAL::cross_product(b - c, cc - c).squared_length()) / area2,
                                          std::sqrt(CGAL::cross_product(cc - c, a - c).squared_length()) / area2,
                                          std::sqrt(CGAL::cross_product(a - c, b - c).squared_length()) / area2};
      Row& row = rows[n];
      for (int j = 0; j < 3; ++j) {
        row.v[j] = static_cast<int>(vs[j].idx());
        row.coef[j] = bary[j] * (nf * normals[vs[j]]);
      }
      row.r = nf * (q - c);
    }
    std::vector<Eigen::Triplet<double>> trip;
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(N));
    size_t used = 0;
    for (const Row& row : rows) {
      if (row.v[0] < 0) continue;
      for (int j = 0; j < 3; ++j) {
        rhs(row.v[j]) += row.coef[j] * row.r;
        for (int l = 0; l < 3; ++l) trip.emplace_back(row.v[j], row.v[l], row.coef[j] * row.coef[l]);
      }
      ++used;
    }
    if (used == 0) {  // no point near the skin: nothing to fit
      sm->remove_property_map(normals);
      break;
    }
    // λ scaled by the points per vertex, so that the balance does not depend on the density.
    const double per_vertex = static_cast<double>(used) / static_cast<double>(std::max<size_t>(sm->number_of_vertices(), 1));
    const double lambda = o.smoothness * per_vertex, mu = 1e-3 * per_vertex;
    for (const auto e : sm->edges()) {
      const auto i = static_cast<int>(sm->vertex(e, 0).idx()), j = static_cast<int>(sm->vertex(e, 1).idx());
      trip.emplace_back(i, i, lambda);
      trip.emplace_back(j, j, lambda);
      trip.emplace_back(i, j, -lambda);
      trip.emplace_back(j, i, -lambda);
    }
    for (size_t i = 0; i < N; ++i) trip.emplace_back(static_cast<int>(i), static_cast<int>(i), mu + (sm->is_removed(SM::Vertex_index(static_cast<SM::size_type>(i))) ? 1.0 : 0.0));
    Eigen::SparseMatrix<double> A(static_cast<Eigen::Index>(N), static_cast<Eigen::Index>(N));
    A.setFromTriplets(trip.begin(), trip.end());
    // Conjugate gradients (the matrix is symmetric positive definite and diagonally heavy),
    // from zero moves.
    Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> cg;
    cg.setTolerance(1e-8);
    cg.compute(A);
    const Eigen::VectorXd t = cg.solve(rhs);
    if (cg.info() != Eigen::Success) {
      sm->remove_property_map(normals);
      break;
    }
    for (const auto v : sm->vertices()) {
      const size_t i = v.idx();
      const auto& nn = normals[v];
      const double len = std::sqrt(nn.squared_length());
      double step = t(static_cast<Eigen::Index>(i));
      if (!std::isfinite(step) || !(len > 0.5)) continue;
      step = std::clamp(total[i] + step, -o.max_move_mm, o.max_move_mm) - total[i];
      total[i] += step;
      sm->point(v) = sm->point(v) + (step / len) * nn;
    }
    sm->remove_property_map(normals);
    f.points = used;
  }
  for (const auto v : sm->vertices()) {
    const double m = std::abs(total[v.idx()]);
    if (m > 1e-6) ++f.moved;
    f.mean_move_mm += m;
    f.max_move_mm = std::max(f.max_move_mm, m);
  }
  f.mean_move_mm /= static_cast<double>(std::max<size_t>(sm->number_of_vertices(), 1));
  return f;
}

// The skin is written in single precision (skin.ply's floats); the skin in memory — what the
// crossing test, the patches, the binding and the report measure — is made the same.
//
// Each coordinate goes through a volatile float: GCC 12.2 at -O2 and -O3 vectorises the
// (double)(float) round trip of two neighbouring coordinates (x, y) and drops it, so that only
// z was rounded — a skin read back from skin.ply differed from the one in memory by up to
// 1e-5 mm (tests/test_skin.cpp, PlyCarriesTheLabelsAndIsTheSkinInMemory).
namespace {
K::Point_3 as_written(const K::Point_3& p) {
  const auto round = [](double d) {
    volatile float f = static_cast<float>(d);
    return static_cast<double>(f);
  };
  return K::Point_3(round(p.x()), round(p.y()), round(p.z()));
}
}  // namespace

void round_as_written(SM* sm) {
  for (const auto v : sm->vertices()) sm->point(v) = as_written(sm->point(v));
}

// Where a move made the skin cross itself (a thin web pulled through its other side), those
// triangles' corners go back, until nothing crosses (the stage's own check, done here). The
// test is made on the positions as they will be written, so that what it says is true of the
// file: two triangles a few micrometres apart in double can cross once rounded.
Crossings take_back_crossings(SM* sm, const std::vector<K::Point_3>& before_exact) {
  round_as_written(sm);
  std::vector<K::Point_3> before(before_exact.size());
  for (size_t i = 0; i < before.size(); ++i) before[i] = as_written(before_exact[i]);
  Crossings c;
  for (int round = 0; round < 10; ++round) {
    std::vector<std::pair<SM::Face_index, SM::Face_index>> pairs;
    PMP::self_intersections(*sm, std::back_inserter(pairs));
    c.self_intersects = !pairs.empty();
    if (pairs.empty()) break;
    for (const auto& [a, b] : pairs)
      for (const auto fc : {a, b})
        for (auto v : CGAL::vertices_around_face(sm->halfedge(fc), *sm))
          if (sm->point(v) != before[v.idx()]) sm->point(v) = before[v.idx()], ++c.reverted;
  }
  return c;
}

}  // namespace handskin::skin_steps
