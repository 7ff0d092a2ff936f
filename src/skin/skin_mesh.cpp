#include "skin/skin_mesh.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/corefinement.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_simplification/Edge_collapse_visitor_base.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/GarlandHeckbert_plane_policies.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>

#include "core/atomic_file.hpp"
#include "core/dof.hpp"
#include "core/errors.hpp"
#include "mesh/from_cgal.hpp"
#include "skin/principal_axes.hpp"
#include "skin/profile.hpp"

namespace handskin {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using SM = CGAL::Surface_mesh<K::Point_3>;
namespace PMP = CGAL::Polygon_mesh_processing;
using profile::kTwoPi;
using profile::Profile;
using profile::segment_distance2;
using profile::wrap;
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

constexpr double kDeg = M_PI / 180.0;
// A digit's links may lie this far from the middle of its sections' extent (the larger of
// the two): a rig that fits puts them within ~1 mm (the bones lie a little dorsal); 4 mm off
// already gives 3.5–4 mm (measured on the fixture, docs/skin.md).
constexpr double kMaxAxisOffsetMm = 2.5, kMaxAxisOffsetShare = 0.3;

/// A ring's plane: polar centre `o`, in-plane axes u, v, normal n (u × v = n, pointing along
/// the tube toward its far end). Angles are sampled on an ellipse of half-axes a (along u)
/// and b (along v), so a flat palm section gets its points spread along the contour.
struct Station {
  Eigen::Vector3d o, u, v, n;
  double a = 1, b = 1;
};

struct TubeBuild {
  int id = 0;
  std::vector<Station> st;
  std::vector<std::vector<Eigen::Vector2d>> slab;  ///< per station: in-plane points relative to o
  std::vector<Eigen::Vector3d> beyond;            ///< points past the last station (fingertip dome)
  std::vector<std::vector<Eigen::Vector3d>> rings;
  std::vector<int> ring_station;
  std::vector<Eigen::Vector3d> ring_centre;
  std::optional<Eigen::Vector3d> pole;
  SkinTubeReport report;
};

// Which tube a link's points go to: the carpus and the four metacarpals make the palm; the
// thumb's three links the thumb; the phalanges of a finger its tube.
int tube_of_bone(const Bone& b) {
  if (b.joint == 0) return static_cast<int>(SkinTube::Palm);
  for (int f = 0; f < kFingerCount; ++f) {
    const auto chain = finger_chain(static_cast<Finger>(f));
    if (std::find(chain.begin(), chain.end(), b.joint) == chain.end()) continue;
    if (f == 0) return static_cast<int>(SkinTube::Thumb);
    return b.joint == chain.front() ? static_cast<int>(SkinTube::Palm) : 1 + f;
  }
  return static_cast<int>(SkinTube::Palm);
}

Station frame_at(const Eigen::Vector3d& o, const Eigen::Vector3d& n_in) {
  Station s;
  s.o = o;
  s.n = n_in.normalized();
  Eigen::Vector3d v = Eigen::Vector3d::UnitZ() - Eigen::Vector3d::UnitZ().dot(s.n) * s.n;  // back of the hand
  if (v.norm() < 1e-6) v = Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitY().dot(s.n) * s.n;
  s.v = v.normalized();
  s.u = s.v.cross(s.n);
  return s;
}

// A polyline with arc length, extended straight beyond both ends.
struct Polyline {
  std::vector<Eigen::Vector3d> p;
  std::vector<double> s;
  explicit Polyline(std::vector<Eigen::Vector3d> pts) : p(std::move(pts)) {
    s.push_back(0);
    for (size_t i = 1; i < p.size(); ++i) s.push_back(s.back() + (p[i] - p[i - 1]).norm());
  }
  Eigen::Vector3d at(double t) const {
    size_t i = 0;
    while (i + 2 < p.size() && t > s[i + 1]) ++i;
    const double L = std::max(s[i + 1] - s[i], 1e-9);
    return p[i] + (t - s[i]) / L * (p[i + 1] - p[i]);
  }
  Eigen::Vector3d tangent(double t, double h) const { return (at(t + h) - at(t - h)).normalized(); }
  // Arc length of the point of the (extended) polyline nearest to q.
  double project(const Eigen::Vector3d& q) const {
    double best = 1e300, bs = 0;
    for (size_t i = 0; i + 1 < p.size(); ++i) {
      const Eigen::Vector3d d = p[i + 1] - p[i];
      const double L2 = std::max(d.squaredNorm(), 1e-12);
      double t = (q - p[i]).dot(d) / L2;
      const double lo = i == 0 ? -1e9 : 0, hi = i + 2 == p.size() ? 1e9 : 1;
      t = std::clamp(t, lo, hi);
      const double dist = (p[i] + t * d - q).squaredNorm();
      if (dist < best) best = dist, bs = s[i] + t * std::sqrt(L2);
    }
    return bs;
  }
};

// Real spherical harmonics to degree 2 of a unit direction (local x, y, z).
Eigen::Matrix<double, 9, 1> sh9(const Eigen::Vector3d& d) {
  Eigen::Matrix<double, 9, 1> r;
  r << 1, d.x(), d.y(), d.z(), d.x() * d.y(), d.x() * d.z(), d.y() * d.z(), d.x() * d.x() - d.y() * d.y(),
      3 * d.z() * d.z() - 1;
  return r;
}

// Give each point of a tube to the station whose plane is nearest (within its slab); points
// past the last plane go to `beyond` when the tube ends in a dome.
void fill_slabs(TubeBuild* t, const std::vector<Eigen::Vector3d>& pts, double h, bool dome) {
  const size_t K = t->st.size();
  t->slab.assign(K, {});
  std::vector<int> where(pts.size(), -1);  // station, K: beyond the last, -1: none
#pragma omp parallel for schedule(static)
  for (long i = 0; i < static_cast<long>(pts.size()); ++i) {
    const Eigen::Vector3d& q = pts[i];
    // The planes are ordered along the tube and never cross within it, so the signed
    // distance falls along the stations: bisect for its sign change.
    auto dist = [&](size_t k) { return t->st[k].n.dot(q - t->st[k].o); };
    size_t a = 0, b = K;  // first station with a negative distance lies in [a, b]
    while (a < b) {
      const size_t m = (a + b) / 2;
      if (dist(m) >= 0) a = m + 1;
      else b = m;
    }
    size_t best = a;
    double bsigned = a < K ? dist(a) : 1e300;
    if (a > 0 && (a == K || std::abs(dist(a - 1)) < std::abs(bsigned))) best = a - 1, bsigned = dist(a - 1);
    const double bd = std::abs(bsigned);
    if (best + 1 == K && bsigned > 0.5 * h) where[i] = dome ? static_cast<int>(K) : -1;
    else if ((best == 0 && bsigned < -0.5 * h) || bd > 0.75 * h) where[i] = -1;
    else where[i] = static_cast<int>(best);
  }
  for (size_t i = 0; i < pts.size(); ++i) {
    if (where[i] < 0) continue;
    if (where[i] == static_cast<int>(K)) {
      t->beyond.push_back(pts[i]);
      continue;
    }
    const Station& s = t->st[where[i]];
    const Eigen::Vector3d r = pts[i] - s.o;
    t->slab[where[i]].emplace_back(r.dot(s.u), r.dot(s.v));
  }
}

// Resample every station's ring: polar profile about the station's centre, a fixed number of
// angles on the station's ellipse, smoothing over neighbouring stations, and rings without
// enough samples filled from their measured neighbours (roots shrink into the palm).
void resample_rings(TubeBuild* t, int M, const SkinOptions& o, bool shrink_root) {
  const size_t K = t->st.size();
  const double window = o.window_deg * kDeg, bridge = 0.2;
  std::vector<std::optional<std::vector<double>>> rho(K);
  std::vector<std::vector<double>> phi(K);
#pragma omp parallel for schedule(dynamic)
  for (long kk = 0; kk < static_cast<long>(K); ++kk) {
    const size_t k = static_cast<size_t>(kk);
    const Station& s = t->st[k];
    for (int j = 0; j < M; ++j) {
      const double psi = kTwoPi * j / M;
      phi[k].push_back(wrap(std::atan2(s.b * std::sin(psi), s.a * std::cos(psi))));
    }
    const auto& g = t->slab[k];
    if (static_cast<long>(g.size()) < std::max<long>(o.slicing.min_points, 10)) continue;
    // Samples more than 2.5 times the median radius out are not this tube's section (a
    // neighbouring digit's skin that reached the slab, where a curled finger passes near).
    std::vector<double> radii;
    for (const auto& p : g) radii.push_back(p.norm());
    std::nth_element(radii.begin(), radii.begin() + radii.size() / 2, radii.end());
    const double ceiling = 2.5 * radii[radii.size() / 2];
    std::vector<std::pair<double, double>> pr;
    for (const auto& p : g)
      if (p.norm() <= ceiling) pr.emplace_back(wrap(std::atan2(p.y(), p.x())), p.norm());
    std::sort(pr.begin(), pr.end());
    Profile P;
    for (const auto& [a, r] : pr) P.phi.push_back(a), P.rho.push_back(r);
    double unseen = 0;
    for (size_t i = 0; i < P.phi.size(); ++i) {
      const double gap = i + 1 < P.phi.size() ? P.phi[i + 1] - P.phi[i] : P.phi.front() + kTwoPi - P.phi.back();
      if (gap > bridge) unseen += gap;
    }
    if (kTwoPi - unseen < o.min_coverage_deg * kDeg) continue;
    std::vector<double> r;
    std::vector<double> sorted_rho = P.rho;
    std::nth_element(sorted_rho.begin(), sorted_rho.begin() + sorted_rho.size() / 2, sorted_rho.end());
    const double floor = 0.3 * sorted_rho[sorted_rho.size() / 2];
    // A bridge across an unseen gap never reaches beyond 1.2 times the farthest sample: a
    // circle through a nearly straight arc (a curled finger cut at a slant) would bulge far.
    const double roof = 1.2 * *std::max_element(P.rho.begin(), P.rho.end());
    for (int j = 0; j < M; ++j) r.push_back(std::clamp(P.at_bridged(phi[k][j], window, bridge), floor, roof));
    rho[k] = std::move(r);
  }
  // Wrinkles: per angle index, a quadratic least-squares fit over ± m neighbouring rings
  // (Savitzky–Golay) predicts each radius; one that strays from it by more than wrinkle_mm
  // is replaced by the fit. Radii the neighbours agree with are kept as measured (a plain
  // average would shrink every profile curved along the tube). Rings without all their
  // neighbours measured keep their own radii.
  const int m = o.smoothing_rings;
  std::vector<double> w;
  for (int i = -m; i <= m; ++i)
    w.push_back((3.0 * (3 * m * m + 3 * m - 1) - 15.0 * i * i) / ((2 * m + 1) * (4.0 * m * m + 4 * m - 3)));
  std::vector<std::optional<std::vector<double>>> smooth(K);
  for (size_t k = 0; k < K; ++k) {
    if (!rho[k]) continue;
    bool all = m > 0;
    for (int d = -m; d <= m && all; ++d) {
      const long kk = static_cast<long>(k) + d;
      all = kk >= 0 && kk < static_cast<long>(K) && rho[kk].has_value();
    }
    if (!all) {
      smooth[k] = rho[k];
      continue;
    }
    std::vector<double> r = *rho[k];
    for (int j = 0; j < M; ++j) {
      double fit = 0;
      for (int d = -m; d <= m; ++d) fit += w[d + m] * (*rho[k + d])[j];
      if (std::abs(fit - r[j]) > o.wrinkle_mm) r[j] = std::max(fit, 0.3 * r[j]);
    }
    smooth[k] = std::move(r);
  }
  // Fill: between measured rings by linear interpolation, beyond them by copying the
  // nearest (shrinking toward a digit's root so that it stays inside the palm).
  std::vector<size_t> measured;
  for (size_t k = 0; k < K; ++k)
    if (smooth[k]) measured.push_back(k);
  t->report.rings = static_cast<int>(K);
  t->report.measured = static_cast<int>(measured.size());
  t->report.filled = static_cast<int>(K - measured.size());
  t->report.present = !measured.empty();
  if (measured.empty()) return;
  for (size_t k = 0; k < K; ++k) {
    if (smooth[k]) continue;
    std::vector<double> r(M);
    const auto hi = std::lower_bound(measured.begin(), measured.end(), k);
    if (hi == measured.begin()) {
      const double f = shrink_root ? std::max(0.7, 1.0 - 0.05 * static_cast<double>(*hi - k)) : 1.0;
      for (int j = 0; j < M; ++j) r[j] = f * (*smooth[*hi])[j];
    } else if (hi == measured.end()) {
      r = *smooth[measured.back()];
    } else {
      const size_t a = *(hi - 1), b = *hi;
      const double u = static_cast<double>(k - a) / static_cast<double>(b - a);
      for (int j = 0; j < M; ++j) r[j] = (1 - u) * (*smooth[a])[j] + u * (*smooth[b])[j];
    }
    smooth[k] = std::move(r);
  }
  t->rings.clear();
  t->ring_station.clear();
  t->ring_centre.clear();
  for (size_t k = 0; k < K; ++k) {
    const Station& s = t->st[k];
    std::vector<Eigen::Vector3d> ring;
    for (int j = 0; j < M; ++j)
      ring.push_back(s.o + (*smooth[k])[j] * (std::cos(phi[k][j]) * s.u + std::sin(phi[k][j]) * s.v));
    t->rings.push_back(std::move(ring));
    t->ring_station.push_back(static_cast<int>(k));
    t->ring_centre.push_back(s.o);
  }
}

// A fingertip's dome: rings at decreasing polar angles about the last station's centre, and
// the pole. Radii from the points around each direction; where the tip was not seen, from a
// degree-2 spherical-harmonic fit of the radius to the tip's points.
void add_dome(TubeBuild* t, int M, int rings, const SkinOptions& o) {
  const Station& s = t->st.back();
  std::vector<Eigen::Vector3d> dir_pts;  // local (u, v, n) directions and radii
  std::vector<double> rad;
  Eigen::Matrix<double, 9, 9> N = Eigen::Matrix<double, 9, 9>::Zero();
  Eigen::Matrix<double, 9, 1> rhs = Eigen::Matrix<double, 9, 1>::Zero();
  auto local = [&](const Eigen::Vector3d& q) {
    const Eigen::Vector3d r = q - s.o;
    return Eigen::Vector3d(r.dot(s.u), r.dot(s.v), r.dot(s.n));
  };
  // The last slab's points too: they pin the dome's rim. Points beyond 1.6 times the rim's
  // largest radius are another digit's (a curled neighbour's tip), not this dome's.
  double rim_in = 0;
  for (const auto& p : t->rings.back()) rim_in = std::max(rim_in, (p - s.o).norm());
  const double reach = 1.6 * rim_in;
  for (const auto& p2 : t->slab.back()) {
    const Eigen::Vector3d l(p2.x(), p2.y(), 0);
    if (l.norm() > 1e-6 && l.norm() <= reach) dir_pts.push_back(l.normalized()), rad.push_back(l.norm());
  }
  for (const auto& q : t->beyond) {
    const Eigen::Vector3d l = local(q);
    if (l.norm() > 1e-6 && l.norm() <= reach) dir_pts.push_back(l.normalized()), rad.push_back(l.norm());
  }
  for (size_t i = 0; i < rad.size(); ++i) {
    const auto y = sh9(dir_pts[i]);
    N += y * y.transpose();
    rhs += y * rad[i];
  }
  for (int k = 1; k < 9; ++k) N(k, k) += 1e-3 * static_cast<double>(rad.size()) + 1e-9;
  N(0, 0) += 1e-9;
  const Eigen::Matrix<double, 9, 1> c = N.ldlt().solve(rhs);
  const double cos_win = std::cos(3.0 * o.window_deg * kDeg);
  // A fingertip is about as wide as its last ring: the dome's radius stays within 0.3–1.3
  // times the rim's largest (the harmonic fit, unconstrained where a curled tip was not
  // seen, can otherwise throw a spike far out).
  const auto& last = t->rings.back();
  double rim = 0;
  for (const auto& p : last) rim = std::max(rim, (p - s.o).norm());
  auto radius = [&](const Eigen::Vector3d& d) {
    double sum = 0;
    int n = 0;
    for (size_t i = 0; i < rad.size(); ++i)
      if (dir_pts[i].dot(d) >= cos_win) sum += rad[i], ++n;
    const double r = n >= 3 ? sum / n : c.dot(sh9(d));
    return std::clamp(r, std::max(0.3 * rim, 0.5), std::max(1.3 * rim, 0.5));
  };
  for (int i = 1; i <= rings; ++i) {
    const double theta = 0.5 * M_PI * (1.0 - static_cast<double>(i) / (rings + 1));
    std::vector<Eigen::Vector3d> ring;
    for (int j = 0; j < M; ++j) {
      const Eigen::Vector3d r = last[j] - s.o;
      const double phi = std::atan2(r.dot(s.v), r.dot(s.u));
      const Eigen::Vector3d d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
      ring.push_back(s.o + radius(d) * (d.x() * s.u + d.y() * s.v + d.z() * s.n));
    }
    t->rings.push_back(std::move(ring));
    t->ring_station.push_back(-1);
    t->ring_centre.push_back(s.o + std::cos(theta) * radius(Eigen::Vector3d::UnitZ()) * s.n);
  }
  t->pole = s.o + radius(Eigen::Vector3d::UnitZ()) * s.n;
}

// Move each ring point out (or, where the ring is concave, in) by half the sagitta of its
// chords, so that the polygon straddles the curve it samples instead of lying inside it: the
// chords' largest distance from the curve halves (the minimax polygon of a circle).
void straddle(std::vector<Eigen::Vector3d>* ring, const Eigen::Vector3d& centre) {
  const std::vector<Eigen::Vector3d> p = *ring;
  const size_t M = p.size();
  for (size_t j = 0; j < M; ++j) {
    const Eigen::Vector3d &a = p[(j + M - 1) % M], &b = p[j], &c = p[(j + 1) % M];
    const Eigen::Vector3d ab = b - a, bc = c - b, ca = a - c;
    const double area2 = ab.cross(bc).norm();
    if (area2 < 1e-12) continue;
    const double R = ab.norm() * bc.norm() * ca.norm() / (2 * area2);  // circumradius
    const double chord = 0.5 * (ab.norm() + bc.norm());
    Eigen::Vector3d out = (b - 0.5 * (a + c));  // toward the outside of a convex corner
    const bool convex = out.dot(b - centre) > 0;
    const Eigen::Vector3d radial = (b - centre).normalized();
    const double sag = std::min(chord * chord / (8 * R), 0.25 * chord);
    (*ring)[j] = b + (convex ? 0.5 : -0.5) * sag * radial;
  }
}

// The tube's triangles (outward): strips between consecutive rings (each quad split along
// its shorter diagonal), a flat fan over the first ring, a pole fan or a flat fan at the end.
void tube_mesh(const TubeBuild& t, std::vector<Eigen::Vector3d>* V, std::vector<std::array<int, 3>>* F,
               std::vector<int>* ring_of) {
  const int M = static_cast<int>(t.rings.front().size());
  V->clear(), F->clear(), ring_of->clear();
  for (size_t k = 0; k < t.rings.size(); ++k) {
    std::vector<Eigen::Vector3d> ring = t.rings[k];
    straddle(&ring, t.ring_centre[k]);
    for (const auto& p : ring) V->push_back(p), ring_of->push_back(t.ring_station[k]);
  }
  auto id = [&](size_t k, int j) { return static_cast<int>(k) * M + ((j % M) + M) % M; };
  for (size_t k = 0; k + 1 < t.rings.size(); ++k)
    for (int j = 0; j < M; ++j) {
      const int a = id(k, j), b = id(k, j + 1), c = id(k + 1, j + 1), d = id(k + 1, j);
      if (((*V)[a] - (*V)[c]).squaredNorm() <= ((*V)[b] - (*V)[d]).squaredNorm())
        F->push_back({a, b, c}), F->push_back({a, c, d});
      else
        F->push_back({a, b, d}), F->push_back({b, c, d});
    }
  auto centroid = [&](size_t k) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const auto& p : t.rings[k]) c += p;
    return Eigen::Vector3d(c / M);
  };
  const int root = static_cast<int>(V->size());
  V->push_back(centroid(0)), ring_of->push_back(-1);
  for (int j = 0; j < M; ++j) F->push_back({root, id(0, j + 1), id(0, j)});
  const size_t L = t.rings.size() - 1;
  const int end = static_cast<int>(V->size());
  V->push_back(t.pole ? *t.pole : centroid(L)), ring_of->push_back(-1);
  for (int j = 0; j < M; ++j) F->push_back({end, id(L, j), id(L, j + 1)});
}

SM to_surface_mesh(const std::vector<Eigen::Vector3d>& V, const std::vector<std::array<int, 3>>& F) {
  SM sm;
  std::vector<SM::Vertex_index> vi;
  for (const auto& p : V) vi.push_back(sm.add_vertex(K::Point_3(p.x(), p.y(), p.z())));
  for (const auto& f : F) HS_CHECK(sm.add_face(vi[f[0]], vi[f[1]], vi[f[2]]) != SM::null_face(), "face rejected");
  return sm;
}

using Origin = SM::Property_map<SM::Vertex_index, std::pair<int, int>>;

/// Edge-collapse filter: refuses a placement that turns any surviving triangle of the
/// collapse's star by more than the angle whose cosine is `cos_max` (CGAL's
/// Bounded_normal_change_filter only refuses flips, i.e. 90°, which still lets the thin web
/// and fingertip strips crease).
struct NormalDeviationFilter {
  double cos_max;
  template <class Profile>
  boost::optional<typename Profile::Point> operator()(const Profile& profile,
                                                      boost::optional<typename Profile::Point> op) const {
    if (!op) return op;
    const auto& vpm = profile.vertex_point_map();
    const auto& tris = profile.triangles();
    // The first one or two triangles are the ones that vanish with the edge; in the rest, v1
    // is the vertex that moves to the placement.
    size_t first = (profile.left_face_exists() ? 1 : 0) + (profile.right_face_exists() ? 1 : 0);
    for (size_t i = first; i < tris.size(); ++i) {
      const K::Point_3 &p = get(vpm, tris[i].v0), &q = get(vpm, tris[i].v1), &r = get(vpm, tris[i].v2);
      const K::Vector_3 n1 = CGAL::cross_product(p - q, r - q), n2 = CGAL::cross_product(p - *op, r - *op);
      const double d = n1 * n2, l = std::sqrt((n1 * n1) * (n2 * n2));
      if (!(l > 0) || d < cos_max * l) return boost::none;
    }
    return op;
  }
};

/// Stops at the triangle budget (a closed triangle mesh has 3F/2 edges) or when the cheapest
/// collapse would move the surface more than the tolerance (the quadric error is a squared
/// distance).
struct BudgetOrToleranceStop {
  size_t max_edges;
  double max_cost;
  template <class FT, class Profile>
  bool operator()(const FT& cost, const Profile&, std::size_t, std::size_t edges) const {
    return edges <= max_edges || cost > max_cost;
  }
};

/// Keeps each vertex's (tube, ring) through the collapses: the survivor takes the origin of
/// whichever end of the edge its new position lies nearer.
struct OriginVisitor : CGAL::Surface_mesh_simplification::Edge_collapse_visitor_base<SM> {
  Origin* origin;
  template <class Profile>
  void OnCollapsed(const Profile& profile, SM::Vertex_index kept) {
    const auto& p = get(profile.vertex_point_map(), kept);
    const bool first = CGAL::squared_distance(p, profile.p0()) <= CGAL::squared_distance(p, profile.p1());
    (*origin)[kept] = (*origin)[first ? profile.v0() : profile.v1()];
  }
};

/// Quadric-error decimation of a closed mesh to `max_faces`, moving it by at most about
/// `tolerance_mm`, with garbage collected afterwards (the property maps follow).
void decimate(SM* sm, size_t max_faces, double tolerance_mm, Origin origin) {
  namespace SMS = CGAL::Surface_mesh_simplification;
  SMS::GarlandHeckbert_plane_policies<SM, K> quadrics(*sm);
  OriginVisitor visitor;
  visitor.origin = &origin;
  SMS::edge_collapse(*sm, BudgetOrToleranceStop{max_faces * 3 / 2, tolerance_mm * tolerance_mm},
                     CGAL::parameters::get_cost(quadrics.get_cost())
                         .get_placement(quadrics.get_placement())
                         .filter(NormalDeviationFilter{std::cos(20.0 * kDeg)})
                         .visitor(visitor));
  sm->collect_garbage();
}

}  // namespace

const char* skin_tube_name(int tube) {
  static const char* names[kSkinTubes] = {"palm", "thumb", "index", "middle", "ring", "little"};
  return tube >= 0 && tube < kSkinTubes ? names[tube] : "?";
}

bool SkinOptions::IsValid(std::string* error) const {
  if (!slicing.IsValid(error)) return false;
  auto bad = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (smoothing_rings < 0 || smoothing_rings > 5) return bad("skin.smoothing_rings must be in [0, 5]");
  if (!(wrinkle_mm >= 0 && wrinkle_mm <= 10)) return bad("skin.wrinkle_mm must be in [0, 10]");
  if (max_triangles != 0 && (max_triangles < 1000 || max_triangles > 1000000))
    return bad("skin.max_triangles must be 0 (no decimation) or in [1000, 1000000]");
  if (!(decimation_tolerance_mm > 0 && decimation_tolerance_mm <= 1)) return bad("skin.decimation_tolerance_mm must be in (0, 1]");
  if (!(thumb_overlap_mm >= 0 && thumb_overlap_mm <= 20)) return bad("skin.thumb_overlap_mm must be in [0, 20]");
  if (cap_rings < 1 || cap_rings > 20) return bad("skin.cap_rings must be in [1, 20]");
  if (!(window_deg > 0 && window_deg <= 20)) return bad("skin.window_deg must be in (0, 20]");
  if (!(min_coverage_deg >= 90 && min_coverage_deg <= 360)) return bad("skin.min_coverage_deg must be in [90, 360]");
  return true;
}

bool SkinResult::watertight() const {
  return health.closed() && health.manifold() && health.components == 1 && health.volume_mm3 > 0 &&
         !(self_intersection_checked && self_intersects);
}

SkinResult build_skin(const std::vector<Eigen::Vector3d>& points, const Rig& rig, const SkinOptions& o,
                      const std::function<void(const std::string&)>& progress) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("skin options", err);
  if (points.size() < 1000)
    throw InputError("merged cloud", "only " + std::to_string(points.size()) + " points to build a skin from");
  auto say = [&](const std::string& m) {
    if (progress) progress(m);
  };
  const auto t0 = Clock::now();
  SkinResult R;
  R.bones = bones_from_rig(rig);
  const Eigen::Isometry3d T = hand_frame_from_rig(rig);  // rig → hand frame (X along the hand, Z back)
  const Eigen::Isometry3d Ti = T.inverse();
  std::vector<Eigen::Vector3d> q(points.size());
  for (size_t i = 0; i < points.size(); ++i) q[i] = T * points[i];
  std::array<Eigen::Vector3d, kJointCount> J;
  for (int j = 0; j < kJointCount; ++j) J[j] = T * rig.joints[j];
  const size_t nb = R.bones.size();
  std::vector<Eigen::Vector3d> A(nb), B(nb);
  std::vector<int> bone_tube(nb);
  for (size_t b = 0; b < nb; ++b) A[b] = T * R.bones[b].a, B[b] = T * R.bones[b].b, bone_tube[b] = tube_of_bone(R.bones[b]);

  // --- the rig must sit in the cloud: the palm's joints (wrist, metacarpal bases and heads)
  // inside its bounding box, give or take 15 mm. A digit's outer joints may lie outside it:
  // that digit is then missing from the scan, which is a warning further on. ---
  Eigen::Vector3d lo = q.front(), hi = q.front();
  for (const auto& p : q) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  std::vector<int> palm_joints = {0};
  for (int f = 0; f < kFingerCount; ++f) {
    const auto c = finger_chain(static_cast<Finger>(f));
    palm_joints.push_back(c[0]);
    palm_joints.push_back(c[1]);
  }
  for (int j : palm_joints)
    if (((J[j].array() < lo.array() - 15).any() || (J[j].array() > hi.array() + 15).any()))
      throw InputError("rig", std::string("joint '") + joints()[j].name +
                                  "' lies outside the merged cloud (more than 15 mm beyond its bounding box); is the "
                                  "rig in the palm frame of this scan?");

  // --- each point to the tube of its nearest link (3D distance to the link segment) ---
  std::vector<std::vector<Eigen::Vector3d>> tube_pts(kSkinTubes);
  std::vector<Eigen::Vector3d> palm_pts;  // the palm's planes take every non-thumb point up to the webs
  // Thumb and palm share the points within thumb_overlap_mm of their boundary, so that both
  // tubes follow the thenar skin across it and the union leaves no groove there.
  const double overlap = o.thumb_overlap_mm;
  constexpr int kThumb = static_cast<int>(SkinTube::Thumb);
  std::vector<std::uint8_t> label(q.size()), shared(q.size());
  // Candidate links per 4 mm cell. The distance to a segment changes by at most r, the cell's
  // half-diagonal, across the cell; so a link more than 2r + overlap farther from the cell's
  // centre than the nearest one can neither be a point's nearest nor matter to the shared
  // band. Only the candidates are measured (about a quarter of the links); results are those
  // of measuring every link, ties included (candidates keep the links' order).
  constexpr double kCell = 4.0;
  const double cell_r = 0.5 * std::sqrt(3.0) * kCell;
  const Eigen::Array3i cells = ((hi - lo) / kCell).array().floor().cast<int>() + 1;
  auto cell_of = [&](const Eigen::Vector3d& p) {
    const Eigen::Array3i c = ((p - lo) / kCell).array().floor().cast<int>().min(cells - 1).max(0);
    return (static_cast<size_t>(c.z()) * cells.y() + c.y()) * cells.x() + c.x();
  };
  std::vector<std::vector<std::uint8_t>> candidates(static_cast<size_t>(cells.prod()));
#pragma omp parallel for schedule(static)
  for (long c = 0; c < static_cast<long>(candidates.size()); ++c) {
    const long x = c % cells.x(), y = (c / cells.x()) % cells.y(), z = c / (cells.x() * cells.y());
    const Eigen::Vector3d centre = lo + kCell * Eigen::Vector3d(x + 0.5, y + 0.5, z + 0.5);
    std::vector<double> d(nb);
    double dmin = 1e300;
    for (size_t b = 0; b < nb; ++b) dmin = std::min(dmin, d[b] = std::sqrt(segment_distance2(centre, A[b], B[b])));
    for (size_t b = 0; b < nb; ++b)
      if (d[b] <= dmin + 2 * cell_r + overlap) candidates[c].push_back(static_cast<std::uint8_t>(b));
  }
#pragma omp parallel for schedule(static)
  for (long i = 0; i < static_cast<long>(q.size()); ++i) {
    const Eigen::Vector3d& p = q[i];
    size_t best = 0;
    double bd = 1e300, best_thumb = 1e300, best_other = 1e300;
    for (const size_t b : candidates[cell_of(p)]) {
      const double d = segment_distance2(p, A[b], B[b]);
      if (d < bd) bd = d, best = b;
      double& group = bone_tube[b] == kThumb ? best_thumb : best_other;
      group = std::min(group, d);
    }
    label[i] = static_cast<std::uint8_t>(bone_tube[best]);
    const double dt = std::sqrt(best_thumb), dn = std::sqrt(best_other);
    shared[i] = label[i] == kThumb ? dn < dt + overlap : dt < dn + overlap;
  }
  for (size_t i = 0; i < q.size(); ++i) {
    tube_pts[label[i]].push_back(q[i]);
    if (label[i] != kThumb || shared[i]) palm_pts.push_back(q[i]);
    if (label[i] != kThumb && shared[i]) tube_pts[kThumb].push_back(q[i]);
  }
  const double x0 = lo.x();
  const Eigen::Vector3d tip_mid = J[finger_chain(Finger::Middle).back()];
  const double h = std::max((tip_mid.x() - x0) / o.slicing.planes, 0.5);  // ring spacing, mm

  // --- the finger webs: along the mid-line between neighbouring fingers, where the skin ends ---
  const int pps = o.slicing.points_per_segment;
  for (int f = 1; f + 1 < kFingerCount; ++f) {
    const auto c1 = finger_chain(static_cast<Finger>(f)), c2 = finger_chain(static_cast<Finger>(f + 1));
    const Eigen::Vector3d m0 = 0.5 * (J[c1[1]] + J[c2[1]]);
    Eigen::Vector3d dir = (J[c1[2]] - J[c1[1]]).normalized() + (J[c2[2]] - J[c2[1]]).normalized();
    dir.z() = 0;
    dir.normalize();
    const double len = 0.5 * ((J[c1[2]] - J[c1[1]]).norm() + (J[c2[2]] - J[c2[1]]).norm());
    std::vector<Eigen::Vector2d> near;
    for (const auto& p : q)
      if ((p - m0).head<2>().norm() < len + 5) near.emplace_back((p - m0).head<2>());
    double web = -1;
    for (double s = 0; s <= len; s += 0.5) {
      const Eigen::Vector2d c = s * dir.head<2>();
      bool any = false;
      for (const auto& p : near)
        if ((p - c).squaredNorm() < 1.5 * 1.5) {
          any = true;
          break;
        }
      if (any) web = s;
      else if (s - web > 2.0) break;
    }
    if (web < 0) {
      R.warnings.push_back(std::string("no skin found between the ") + skin_tube_name(f + 1) + " and " +
                           skin_tube_name(f + 2) + " finger roots; the web is put at the knuckles");
      web = 0;
    } else if (web >= len) {
      R.warnings.push_back(std::string("the ") + skin_tube_name(f + 1) + " and " + skin_tube_name(f + 2) +
                           " fingers touch along their whole proximal phalanx; the web is put at the middle joints");
    }
    R.webs.push_back(m0 + web * dir);
  }
  // The palm's end plane: vertical, through the webs' line, moved back to the most proximal web.
  std::vector<Eigen::Vector2d> web_xy;
  for (const auto& w : R.webs) web_xy.push_back(w.head<2>());
  Eigen::Matrix2d web_axes;
  Eigen::Vector2d wc;
  principal_axes<2>(web_xy, &web_axes, &wc);
  Eigen::Vector2d nend(web_axes(1, 0), -web_axes(0, 0));
  if (nend.x() < 0) nend = -nend;
  double alpha_end = std::atan2(nend.y(), nend.x());
  alpha_end = std::clamp(alpha_end, -35 * kDeg, 35 * kDeg);
  nend = Eigen::Vector2d(std::cos(alpha_end), std::sin(alpha_end));
  double back = 0;
  for (const auto& w : R.webs) back = std::min(back, nend.dot(w.head<2>() - wc));
  const Eigen::Vector2d end_point = wc + (back - 0.5) * nend;
  const double x_end = end_point.x();  // where the end plane crosses the line y = wc.y
  if (x_end - x0 < 5 * h) throw InputError("rig", "the finger webs lie at the wrist end of the cloud; the rig does not fit it");

  std::vector<TubeBuild> tubes(kSkinTubes);
  // --- palm: planes across the hand's axis from the wrist cut, fanned to the end plane ---
  {
    TubeBuild& t = tubes[0];
    t.id = 0;
    const int K = std::max(3, static_cast<int>(std::ceil((x_end - x0) / h)) + 1);
    const double hp = (x_end - x0) / (K - 1);
    const int fan = std::clamp(static_cast<int>(std::ceil(std::abs(alpha_end) / (2.5 * kDeg))), 1, K - 1);
    for (int k = 0; k < K; ++k) {
      const double ramp = std::clamp(static_cast<double>(k - (K - 1 - fan)) / fan, 0.0, 1.0);
      const double a = alpha_end * ramp;
      t.st.push_back(frame_at(Eigen::Vector3d(x0 + k * hp, wc.y(), 0), Eigen::Vector3d(std::cos(a), std::sin(a), 0)));
    }
    t.st.front().o.x() = x0 + 1e-3;  // the wrist cut: the first ring's slab is all on its distal side
    fill_slabs(&t, palm_pts, hp, false);
    // Polar centre and sampling ellipse per plane: the middle and half-extents of its points,
    // smoothed along the hand.
    std::vector<Eigen::Vector4d> box(K, Eigen::Vector4d::Zero());
    std::vector<bool> ok(K, false);
    for (int k = 0; k < K; ++k) {
      if (t.slab[k].size() < 10) continue;
      Eigen::Vector2d mn = t.slab[k].front(), mx = mn;
      for (const auto& p : t.slab[k]) mn = mn.cwiseMin(p), mx = mx.cwiseMax(p);
      box[k] << 0.5 * (mn + mx), 0.5 * (mx - mn);
      ok[k] = true;
    }
    // Planes without points (a hole in the scan) take their neighbours' centre and ellipse.
    for (int k = 0; k < K; ++k) {
      if (ok[k]) continue;
      int a = k - 1, b = k + 1;
      while (a >= 0 && !ok[a]) --a;
      while (b < K && !ok[b]) ++b;
      if (a < 0 && b >= K) break;
      if (a < 0) box[k] = box[b];
      else if (b >= K) box[k] = box[a];
      else box[k] = box[a] + (box[b] - box[a]) * (static_cast<double>(k - a) / (b - a));
    }
    for (int k = 0; k < K; ++k) ok[k] = box[k](2) > 0;
    for (int pass = 0; pass < 2; ++pass) {
      std::vector<Eigen::Vector4d> sm = box;
      for (int k = 0; k < K; ++k) {
        if (!ok[k]) continue;
        Eigen::Vector4d s = 2 * box[k];
        double w = 2;
        for (int d : {-1, 1})
          if (k + d >= 0 && k + d < K && ok[k + d]) s += box[k + d], w += 1;
        sm[k] = s / w;
      }
      box = sm;
    }
    for (int k = 0; k < K; ++k) {
      if (!ok[k]) continue;
      Station& s = t.st[k];
      const Eigen::Vector2d shift = box[k].head<2>();
      for (auto& p : t.slab[k]) p -= shift;
      s.o += shift.x() * s.u + shift.y() * s.v;
      s.a = std::max(box[k](2), 1.0);
      s.b = std::clamp(box[k](3), s.a / 4, s.a * 4);
    }
    t.report.points = palm_pts.size();
    resample_rings(&t, 8 * pps, o, false);
  }
  // --- digits: planes perpendicular to their own links, from the root to the tip's dome ---
  for (int f = 0; f < kFingerCount; ++f) {
    TubeBuild& t = tubes[1 + f];
    t.id = 1 + f;
    const auto chain = finger_chain(static_cast<Finger>(f));
    std::vector<Eigen::Vector3d> axis;
    for (size_t k = f == 0 ? 0 : 1; k < chain.size(); ++k) axis.push_back(J[chain[k]]);
    const Polyline pl(axis);
    const auto& pts = tube_pts[1 + f];
    t.report.points = pts.size();
    t.report.name = skin_tube_name(1 + f);
    if (pts.size() < 50) {
      t.report.present = false;
      continue;
    }
    // Where the tip ends (robust maximum of the arc length) and how wide it is there.
    std::vector<double> s_of(pts.size());
#pragma omp parallel for schedule(static)
    for (long i = 0; i < static_cast<long>(pts.size()); ++i) s_of[i] = pl.project(pts[i]);
    std::vector<double> ss = s_of;
    std::sort(ss.begin(), ss.end());
    const double s_max = ss[ss.size() - std::min<size_t>(5, ss.size())];
    std::vector<double> rr;
    for (size_t i = 0; i < pts.size(); ++i)
      if (s_of[i] > s_max - 12 && s_of[i] < s_max - 6) {
        const Eigen::Vector3d c = pl.at(s_of[i]);
        rr.push_back((pts[i] - c).norm());
      }
    double r_tip = 6;
    if (rr.size() >= 10) {
      std::nth_element(rr.begin(), rr.begin() + rr.size() / 2, rr.end());
      r_tip = rr[rr.size() / 2];
    }
    const double s_c = s_max - r_tip;
    if (s_c < 2 * h) {
      t.report.present = false;
      continue;
    }
    const int K = std::max(3, static_cast<int>(std::ceil(s_c / h)) + 1);
    const double hs = s_c / (K - 1);
    for (int k = 0; k < K; ++k) t.st.push_back(frame_at(pl.at(k * hs), pl.tangent(k * hs, hs)));
    fill_slabs(&t, pts, hs, true);
    {
      std::vector<double> off, rad;
      for (const auto& g : t.slab) {
        if (g.size() < 20) continue;
        Eigen::Vector2d mn = g.front(), mx = mn;
        for (const auto& p : g) mn = mn.cwiseMin(p), mx = mx.cwiseMax(p);
        off.push_back((0.5 * (mn + mx)).norm());
        rad.push_back(0.25 * ((mx - mn).x() + (mx - mn).y()));
      }
      auto median = [](std::vector<double> v) {
        std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
        return v[v.size() / 2];
      };
      if (off.size() >= 3) t.report.axis_offset_mm = median(off), t.report.section_radius_mm = median(rad);
    }
    resample_rings(&t, 2 * pps, o, true);
    if (!t.report.present) continue;
    // Neighbouring fingers' tubes meet in the webs. Where a ring point lies nearer the
    // neighbour's phalanges than its own (less a margin) it is pulled back along its ray,
    // so that two tubes never touch — near-tangent contacts would make the stitching
    // fragile — and the web between them is the palm's.
    if (f >= 1) {
      auto chain_distance = [&](int finger, const Eigen::Vector3d& p) {
        const auto c = finger_chain(static_cast<Finger>(finger));
        double best = 1e300;
        for (size_t k = 1; k + 1 < c.size(); ++k) best = std::min(best, segment_distance2(p, J[c[k]], J[c[k + 1]]));
        return std::sqrt(best);
      };
      const double margin = 0.5;
      for (size_t k = 0; k < t.rings.size(); ++k)
        for (auto& p : t.rings[k])
          for (int g : {f - 1, f + 1}) {
            if (g < 1 || g >= kFingerCount) continue;
            auto clear = [&](const Eigen::Vector3d& x) { return chain_distance(g, x) - chain_distance(f, x) >= margin; };
            if (clear(p)) continue;
            const Eigen::Vector3d c = t.ring_centre[k];
            double lo = 0.3, hi = 1.0;  // fraction of the radius: lo clear (checked), hi not
            if (!clear(c + lo * (p - c))) continue;
            for (int it = 0; it < 12; ++it) {
              const double mid = 0.5 * (lo + hi);
              (clear(c + mid * (p - c)) ? lo : hi) = mid;
            }
            p = c + lo * (p - c);
          }
    }
    add_dome(&t, 2 * pps, o.cap_rings, o);
  }
  for (auto& t : tubes) {
    t.report.name = skin_tube_name(t.id);
    if (!t.report.present && t.id != 0)
      R.warnings.push_back(std::string("no ") + skin_tube_name(t.id) +
                           (t.id == 1 ? "" : " finger") + " in the scan: the skin is built without it");
    R.tubes.push_back(t.report);
  }
  if (!tubes[0].report.present) throw InputError("merged cloud", "no palm section could be measured");
  // A rig that does not fit the cloud (another scan's, shifted, fingers swapped) puts a
  // digit's links beside the middle of its sections: refused rather than worked around.
  for (const auto& t : tubes) {
    const SkinTubeReport& r = t.report;
    if (t.id == 0 || !r.present || r.section_radius_mm <= 0) continue;
    const double allowed = std::max(kMaxAxisOffsetMm, kMaxAxisOffsetShare * r.section_radius_mm);
    if (r.axis_offset_mm > allowed) {
      char buf[240];
      std::snprintf(buf, sizeof buf,
                    "the %s's links lie %.1f mm from the middle of its sections (allowed %.1f mm): the rig does not "
                    "fit this scan (a rig of another scan, or its fingers swapped?)",
                    skin_tube_name(t.id), r.axis_offset_mm, allowed);
      throw InputError("rig", buf);
    }
  }
  R.seconds_rings = since(t0);
  say("rings resampled (" + std::to_string(static_cast<int>(R.seconds_rings * 1000)) + " ms)");

  // --- tubes to CGAL meshes, stitched by corefinement union ---
  const auto t1 = Clock::now();
  std::map<std::array<double, 3>, std::pair<int, int>> origin;  // exact position → tube, ring
  // The digits, which do not touch one another (the fingers were kept apart above), go in as
  // one mesh of five shells, so that the palm is stitched to all of them in a single
  // corefinement. Corefinement needs inputs free of self-intersections: the palm is checked,
  // and the five digits at once, which covers each digit's own folds as well as digits
  // touching. Only if that check fails is each digit checked on its own, to name the one that
  // folds; if none does, two digits touch (e.g. the thumb lying on the index) and they are
  // stitched one by one instead.
  std::vector<SM> parts;
  std::vector<int> part_tube;
  for (const auto& t : tubes) {
    if (!t.report.present) continue;
    std::vector<Eigen::Vector3d> V;
    std::vector<std::array<int, 3>> F;
    std::vector<int> ring_of;
    tube_mesh(t, &V, &F, &ring_of);
    for (auto& p : V) p = Ti * p;
    for (size_t i = 0; i < V.size(); ++i) origin[{V[i].x(), V[i].y(), V[i].z()}] = {t.id, ring_of[i]};
    parts.push_back(to_surface_mesh(V, F));
    part_tube.push_back(t.id);
  }
  auto check_folds = [&](size_t k) {
    if (PMP::does_self_intersect(parts[k]))
      throw InputError("merged cloud", std::string("the ") + skin_tube_name(part_tube[k]) +
                                           " tube folds into itself; the rig may be badly placed for this scan");
  };
  auto unite = [&](SM& a, SM& b, const std::string& what) {
    SM out;
    if (!PMP::corefine_and_compute_union(a, b, out))
      throw InputError("merged cloud", "the " + what + " cannot be stitched to the palm into a closed manifold");
    return out;
  };
  check_folds(0);
  SM digits;
  for (size_t k = 1; k < parts.size(); ++k) {
    std::vector<SM::Vertex_index> map(parts[k].number_of_vertices());
    for (auto v : parts[k].vertices()) map[v.idx()] = digits.add_vertex(parts[k].point(v));
    for (auto f : parts[k].faces()) {
      std::vector<SM::Vertex_index> tri;
      for (auto v : CGAL::vertices_around_face(parts[k].halfedge(f), parts[k])) tri.push_back(map[v.idx()]);
      digits.add_face(tri[0], tri[1], tri[2]);
    }
  }
  SM skin = std::move(parts.front());  // the palm
  if (parts.size() > 1 && !PMP::does_self_intersect(digits)) {
    skin = unite(skin, digits, "digits");
  } else {
    for (size_t k = 1; k < parts.size(); ++k) check_folds(k);
    for (size_t k = 1; k < parts.size(); ++k) skin = unite(skin, parts[k], skin_tube_name(part_tube[k]) + std::string(" tube"));
  }
  // The union's boundary also bounds any pocket the tubes enclose between them: inward-facing
  // shells inside the skin. They are dropped; a second outward shell would be a digit that
  // does not meet the palm, which is an error. Counting the components first spares the copy
  // into pieces in the usual case of one.
  auto component = skin.add_property_map<SM::Face_index, std::size_t>("f:component", 0).first;
  const std::size_t components = PMP::connected_components(skin, component);
  skin.remove_property_map(component);
  if (components > 1) {
    std::vector<SM> pieces;
    PMP::split_connected_components(skin, pieces);
    SM outer;
    int outward = 0, pockets = 0;
    for (auto& piece : pieces) {
      if (PMP::volume(piece) > 0) {
        ++outward;
        outer = std::move(piece);
      } else {
        ++pockets;
      }
    }
    if (outward != 1)
      throw InputError("merged cloud", "the skin's tubes do not join into one surface (" + std::to_string(outward) +
                                           " separate pieces); the rig may not fit this scan");
    R.pockets_removed = pockets;
    skin = std::move(outer);
  }
  R.seconds_union = since(t1);
  say("tubes stitched (" + std::to_string(static_cast<int>(R.seconds_union * 1000)) + " ms)");

  // --- decimation to the triangle budget (CGAL edge collapse, Garland–Heckbert plane
  // quadrics): the strips are uniform, but the flat back and palm need fewer triangles than
  // the fingers' flanks. A collapse is refused when its quadric error exceeds the tolerance or
  // when it turns a neighbouring triangle by more than 20° (without that guard, collapses fold
  // the skin). OpenMesh's decimater took ~75 ms for 9500 triangles here, most of it spent in
  // the per-halfedge legality checks of its heap set-up; CGAL's takes ~16 ms. Each vertex's
  // origin (tube, ring) follows it through the collapses. ---
  const auto t2 = Clock::now();
  auto origin_of = skin.add_property_map<SM::Vertex_index, std::pair<int, int>>("v:origin", {-1, -1}).first;
  for (auto v : skin.vertices()) {
    const auto& p = skin.point(v);
    if (auto it = origin.find({p.x(), p.y(), p.z()}); it != origin.end()) origin_of[v] = it->second;
  }
  R.triangles_before_decimation = skin.number_of_faces();
  if (o.max_triangles > 0 && skin.number_of_faces() > static_cast<size_t>(o.max_triangles)) {
    decimate(&skin, static_cast<size_t>(o.max_triangles), o.decimation_tolerance_mm, origin_of);
    if (skin.number_of_faces() > static_cast<size_t>(o.max_triangles))
      R.warnings.push_back("the skin keeps " + std::to_string(skin.number_of_faces()) + " triangles (budget " +
                           std::to_string(o.max_triangles) + "): fewer would move it more than " +
                           std::to_string(o.decimation_tolerance_mm).substr(0, 5) + " mm");
  }
  R.mesh = to_trimesh(skin);  // vertices in the order of skin.vertices()
  R.seconds_decimation = since(t2);

  // --- checks, labels, the OpenMesh result ---
  const auto t3 = Clock::now();
  if (o.check_self_intersections) {
    R.self_intersects = PMP::does_self_intersect(skin);
    R.self_intersection_checked = true;
  }
  R.health = mesh_health(R.mesh);
  R.seconds_checks = since(t3);
  const auto V = mesh_vertices(R.mesh);
  size_t vi = 0;
  for (auto v : skin.vertices()) {
    const auto [tube, ring] = origin_of[v];
    const Eigen::Vector3d ph = T * V[vi++];
    int best = 0;
    double bd = 1e300;
    for (size_t b = 0; b < nb; ++b) {
      if (tube > 0 && bone_tube[b] != tube) continue;  // a digit's vertex binds to that digit's links
      const double d = segment_distance2(ph, A[b], B[b]);
      if (d < bd) bd = d, best = static_cast<int>(b);
    }
    R.vertex_bone.push_back(best);
    R.vertex_tube.push_back(tube >= 0 ? tube : bone_tube[best]);
    R.vertex_ring.push_back(ring);
  }
  return R;
}

void save_skin_ply(const std::string& path, const SkinResult& skin) {
  const auto V = mesh_vertices(skin.mesh);
  const auto F = mesh_faces(skin.mesh);
  HS_CHECK(skin.vertex_bone.size() == V.size(), "skin labels do not match its vertices");
  std::string out = "ply\nformat binary_little_endian 1.0\ncomment handskin skin, palm frame, mm\n";
  out += "element vertex " + std::to_string(V.size()) +
         "\nproperty float x\nproperty float y\nproperty float z\nproperty int bone\nproperty int tube\nproperty int "
         "ring\n";
  out += "element face " + std::to_string(F.size()) + "\nproperty list uchar int vertex_indices\nend_header\n";
  auto put = [&](const void* p, size_t n) { out.append(static_cast<const char*>(p), n); };
  for (size_t i = 0; i < V.size(); ++i) {
    const float xyz[3] = {static_cast<float>(V[i].x()), static_cast<float>(V[i].y()), static_cast<float>(V[i].z())};
    const int32_t lab[3] = {skin.vertex_bone[i], skin.vertex_tube[i], skin.vertex_ring[i]};
    put(xyz, sizeof xyz);
    put(lab, sizeof lab);
  }
  for (const auto& f : F) {
    const unsigned char n = 3;
    const int32_t idx[3] = {f[0], f[1], f[2]};
    put(&n, 1);
    put(idx, sizeof idx);
  }
  write_file_atomic(path, out);
}

}  // namespace handskin
