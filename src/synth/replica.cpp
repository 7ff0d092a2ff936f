#include "synth/replica.hpp"

#include <algorithm>
#include <cstdio>
#include <map>
#include <tuple>
#include <utility>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/clip.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/triangulate_faces.h>
#include <CGAL/Surface_mesh.h>

#include "core/dof.hpp"
#include "core/errors.hpp"
#include "mesh/from_cgal.hpp"
#include "mesh/triangle_tree.hpp"
#include "core/random.hpp"
#include "synth/albedo.hpp"

namespace handskin {

namespace {
using cgal::K;
constexpr double kDeg = M_PI / 180.0;


// First surface hit of a ray on the hand (hand frame); nullopt if it misses.
struct RayCaster {
  cgal::TriangleTree tt;
  RayCaster(const std::vector<Eigen::Vector3d>& v, const std::vector<std::array<int, 3>>& f) : tt(v, f) {}
  std::optional<std::pair<Eigen::Vector3d, Eigen::Vector3d>> cast(const Eigen::Vector3d& o,
                                                                   const Eigen::Vector3d& d) const {
    const auto hit = tt.tree.first_intersection(K::Ray_3(K::Point_3(o.x(), o.y(), o.z()), K::Vector_3(d.x(), d.y(), d.z())));
    if (!hit) return std::nullopt;
    const K::Point_3* p = boost::get<K::Point_3>(&hit->first);
    if (!p) return std::nullopt;
    const cgal::Triangle& t = *hit->second;
    const K::Vector_3 n = CGAL::cross_product(t[1] - t[0], t[2] - t[0]);
    return std::make_pair(Eigen::Vector3d(p->x(), p->y(), p->z()), Eigen::Vector3d(n.x(), n.y(), n.z()).normalized());
  }
};

// Largest-smallest difference between two markers' sorted distance lists: a marker is
// identifiable from its distances only if this is large for every other marker.
double min_signature_gap(const std::vector<Eigen::Vector3d>& c) {
  const size_t n = c.size();
  std::vector<std::vector<double>> sig(n);
  for (size_t a = 0; a < n; ++a) {
    for (size_t b = 0; b < n; ++b)
      if (a != b) sig[a].push_back((c[a] - c[b]).norm());
    std::sort(sig[a].begin(), sig[a].end());
  }
  double gap = 1e9;
  for (size_t a = 0; a < n; ++a)
    for (size_t b = a + 1; b < n; ++b) {
      double d = 0;
      for (size_t k = 0; k + 1 < n; ++k) d = std::max(d, std::abs(sig[a][k] - sig[b][k]));
      gap = std::min(gap, d);
    }
  return gap;
}

Eigen::Isometry3d yaw_then(double yaw_deg, const Eigen::Matrix3d& base) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix() * base;
  return T;
}

// The replica sawn flat `saw_mm` proximal of the wrist joint (hand frame: x = -saw_mm), the
// cut closed by a flat face (CGAL's clip with the clipped volume kept closed). The sawn mesh
// must stay one closed piece.
Mesh saw_flat(const std::vector<Eigen::Vector3d>& v, const std::vector<std::array<int, 3>>& f, double saw_mm) {
  using EK = CGAL::Exact_predicates_inexact_constructions_kernel;  // clip corefines: robust predicates
  using SM = CGAL::Surface_mesh<EK::Point_3>;
  SM sm;
  std::vector<SM::Vertex_index> vi;
  for (const auto& p : v) vi.push_back(sm.add_vertex(EK::Point_3(p.x(), p.y(), p.z())));
  for (const auto& t : f)
    if (sm.add_face(vi[t[0]], vi[t[1]], vi[t[2]]) == SM::null_face())
      throw InputError("--mesh", "not a two-manifold triangle mesh; cannot saw it");
  if (!CGAL::is_closed(sm)) throw InputError("--mesh", "the hand mesh is not closed; cannot saw it");
  // clip keeps the plane's negative side: -x - saw_mm < 0, i.e. x > -saw_mm.
  CGAL::Polygon_mesh_processing::clip(sm, EK::Plane_3(-1, 0, 0, -saw_mm), CGAL::parameters::clip_volume(true));
  auto component = sm.add_property_map<SM::Face_index, std::size_t>("f:component").first;
  const bool one_piece = !sm.is_empty() && CGAL::is_closed(sm) &&
                         CGAL::Polygon_mesh_processing::connected_components(sm, component) == 1;
  sm.remove_property_map(component);
  if (!one_piece)
    throw InputError("--saw", "sawing " + std::to_string(saw_mm) + " mm beyond the wrist leaves no single closed hand");
  CGAL::Polygon_mesh_processing::triangulate_faces(sm);
  return to_mesh(sm);
}

}  // namespace

bool ReplicaOptions::IsValid(std::string* error) const {
  if (marker_count < 3 || marker_count > 12) return invalid(error, "marker_count must be in [3, 12]");
  if (!(marker_radius_mm >= 0.5 && marker_radius_mm <= 10)) return invalid(error, "marker_radius_mm must be in [0.5, 10]");
  if (!(min_signature_gap_mm >= 0 && min_signature_gap_mm <= 20)) return invalid(error, "min_signature_gap_mm must be in [0, 20]");
  if (min_marker_returns < 1) return invalid(error, "min_marker_returns must be >= 1");
  if (omit_marker_in_back < -1 || omit_marker_in_back >= marker_count)
    return invalid(error, "omit_marker_in_back must be -1 or a marker index below marker_count");
  if (!(max_yaw_deg >= 0 && max_yaw_deg <= 45)) return invalid(error, "max_yaw_deg must be in [0, 45]");
  if (saw_mm && !(*saw_mm >= 0 && *saw_mm <= 100)) return invalid(error, "saw_mm must be in [0, 100]");
  return true;
}

void icosphere(const Eigen::Vector3d& centre, double radius, int levels, std::vector<Eigen::Vector3d>* vertices,
               std::vector<std::array<int, 3>>* faces) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                                    {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                       {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                       {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                       {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (auto& p : v) p.normalize();
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[a] + v[b]).normalized());
      return mid[key] = static_cast<int>(v.size()) - 1;
    };
    std::vector<std::array<int, 3>> g;
    for (const auto& tri : f) {
      const int a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]), c = midpoint(tri[2], tri[0]);
      g.push_back({tri[0], a, c});
      g.push_back({tri[1], b, a});
      g.push_back({tri[2], c, b});
      g.push_back({a, b, c});
    }
    f.swap(g);
  }
  vertices->clear();
  for (const auto& p : v) vertices->push_back(centre + radius * p);
  *faces = f;
}

namespace {

// The photo of one scan: per pixel, the colour of what the camera sees there (the scanner
// recorded the face and height of the first hit): hand faces come first in the scene, then
// the markers' spheres.
Rgb8Image take_photo(const ScanSimulation& sim, const ScannerOptions& so, const Eigen::Isometry3d& T_scan_hand,
                     const std::vector<Eigen::Vector3d>& hv, const std::vector<std::array<int, 3>>& hf,
                     const SkinAlbedo& albedo) {
  Rgb8Image img;
  img.width = so.points;
  img.height = so.scanlines;
  img.rgb.resize(static_cast<size_t>(img.width) * img.height * 3);
  const Eigen::Isometry3d T_hand_scan = T_scan_hand.inverse();
  for (int i = 0; i < so.scanlines; ++i)
    for (int j = 0; j < so.points; ++j) {
      const size_t idx = static_cast<size_t>(i) * so.points + j;
      const int f = sim.camera_face[idx];
      Eigen::Vector3f c(0.34f, 0.35f, 0.38f);  // the table
      if (f >= static_cast<int>(hf.size())) {
        c = {0.93f, 0.93f, 0.91f};  // a plaster marker
      } else if (f >= 0) {
        const auto& t = hf[static_cast<size_t>(f)];
        const Eigen::Vector3d n = (hv[t[1]] - hv[t[0]]).cross(hv[t[2]] - hv[t[0]]).normalized();
        c = albedo.colour(T_hand_scan * Eigen::Vector3d(i * so.x_step(), j * so.y_step(), sim.camera_z[idx]), n);
      }
      for (int ch = 0; ch < 3; ++ch)
        img.rgb[idx * 3 + ch] = static_cast<std::uint8_t>(std::lround(255.0 * std::clamp(c[ch], 0.f, 1.f)));
    }
  return img;
}

}  // namespace

namespace {

// --- markers: on the ulnar flank, the radial flank and the wrist end, irregularly spaced ---
  // The flanks run out along the little finger and the thumb: rotation precision grows with
  // the markers' spread (docs/registration.md), and those are the replica's widest and
  // longest flanks that both scans see. A right hand's thumb lies on the hand frame's +Y, a
  // left hand's on −Y; a posed hand's thumb may hang palmar of the palm and its fingers arch,
  // so each marker is checked to be seen from above and from below (nothing of the hand
  // over or under it) before the scans are made.
std::vector<Eigen::Vector3d> place_markers(const std::vector<Eigen::Vector3d>& hv, const RayCaster& caster,
                                           const Rig& rig_hand, HandSide side, const ReplicaOptions& ro, Rng& rng) {
  const auto J = [&](const char* n) { return rig_hand.joints[joint_index(n).value()]; };
  const double ys = side == HandSide::Left ? -1.0 : 1.0;  // +: toward the thumb
  const Eigen::Vector3d l0 = J("pinky-finger-metacarpal"), l1 = J("pinky-finger-phalanx-proximal"),
                        l2 = J("pinky-finger-phalanx-intermediate");
  const Eigen::Vector3d t0 = J("thumb-metacarpal"), t1 = J("thumb-phalanx-proximal"), t2 = J("thumb-phalanx-distal");
  auto along = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, double u) {
    return u < 1 ? Eigen::Vector3d(a + u * (b - a)) : Eigen::Vector3d(b + (u - 1) * (c - b));
  };
  // The point at `frac` of the arc length between link units u0 and u1 (u in [0, 1]: the
  // first link, [1, 2]: the second), as a link unit: markers spread evenly in millimetres.
  auto to_u = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, double u0, double u1,
                 double frac) {
    const double L1 = (b - a).norm(), L2 = (c - b).norm();
    auto mm = [&](double u) { return u < 1 ? u * L1 : L1 + (u - 1) * L2; };
    const double t = mm(u0) + frac * (mm(u1) - mm(u0));
    return t < L1 ? t / L1 : 1 + (t - L1) / L2;
  };
  std::vector<Eigen::Vector3d> markers;
  const double r = ro.marker_radius_mm;
  auto seen_from = [&](const Eigen::Vector3d& c, const Eigen::Vector3d& normal, double dir_z) {
    // The sphere's outer half (the part off the flank) must not lie under (or over) the hand.
    Eigen::Vector3d n(normal.x(), normal.y(), 0);
    n.normalize();
    const Eigen::Vector3d t = Eigen::Vector3d::UnitZ().cross(n);
    for (const double side : {-0.5, 0.0, 0.5}) {
      const Eigen::Vector3d o = c + 0.5 * r * n + side * r * t + Eigen::Vector3d(0, 0, dir_z * (r + 0.3));
      if (caster.cast(o, Eigen::Vector3d(0, 0, dir_z))) return false;
    }
    return true;
  };
  // The wrist cut face: the hand's samples within 1 mm of its proximal end, their (y, z) box.
  // Beside it, the forearm's section 15 mm in: a flat cut is nearly as wide as that; an end
  // that is rounded (a hand model's forearm, not a sawn cast) is not, and gives no face for
  // the wrist markers.
  Eigen::Vector2d face_c, face_h, section_h;
  {
    double x0 = 1e300;
    for (const auto& p : hv) x0 = std::min(x0, p.x());
    auto box = [&](double depth) {  // centre and half-extents
      Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e300), hi = -lo;
      for (const auto& p : hv)
        if (p.x() < x0 + depth) lo = lo.cwiseMin(p.tail<2>()), hi = hi.cwiseMax(p.tail<2>());
      return std::pair<Eigen::Vector2d, Eigen::Vector2d>(0.5 * (lo + hi), 0.5 * (hi - lo));
    };
    std::tie(face_c, face_h) = box(1.0);
    section_h = box(15.0).second;
  }
  // A narrower search after many failures: markers nearer the palm (the little finger's
  // metacarpal, the thumb's base), where the flanks are broad and nothing overhangs.
  for (int attempt = 0; attempt < 800 && markers.empty(); ++attempt) {
    const double reach = attempt < 400 ? 1.0 : 0.6;
    std::vector<Eigen::Vector3d> c;
    // Marker slots: 3 ulnar, 3 wrist end, the rest radial (for 9 markers: 3 radial).
    const int n_ulnar = (ro.marker_count + 2) / 3, n_wrist = (ro.marker_count + 1) / 3;
    const int n_radial = ro.marker_count - n_ulnar - n_wrist;
    bool ok = true;
    auto place = [&](const Eigen::Vector3d& origin, const Eigen::Vector3d& dir) {
      const auto hit = caster.cast(origin, dir);
      // Must land on a flank (normal roughly horizontal) seen by both scans.
      if (!hit || std::abs(hit->second.z()) > 0.45 || hit->second.dot(dir) > 0) ok = false;
      else if (!seen_from(hit->first, hit->second, 1.0) || !seen_from(hit->first, hit->second, -1.0)) ok = false;
      else c.push_back(hit->first);
    };
    // Each flank marker is shot at its link from the side, square to it and level (a raised
    // thumb's link points out of the table's plane: a ray along the hand's Y would meet it
    // where the surface faces up or down).
    auto side_of = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, double sign) {
      Eigen::Vector3d n = Eigen::Vector3d::UnitZ().cross(b - a);
      return Eigen::Vector3d(sign * n.normalized());
    };
    for (int k = 0; k < n_ulnar && ok; ++k) {  // little-finger metacarpal to proximal phalanx
      const double u = to_u(l0, l1, l2, 0.3, 0.3 + reach * 1.45, (k + 0.5) / n_ulnar + rng.uniform(-0.08, 0.08));
      const Eigen::Vector3d q = along(l0, l1, l2, u);
      const Eigen::Vector3d n = u < 1 ? side_of(l0, l1, -ys) : side_of(l1, l2, -ys);
      place(q + 200.0 * n + Eigen::Vector3d(0, 0, rng.uniform(-3.0, 1.5)), -n);
    }
    for (int k = 0; k < n_radial && ok; ++k) {  // thumb metacarpal to proximal phalanx
      const double u =
          to_u(t0, t1, t2, 0.5 * reach, 0.5 * reach + reach * 1.2, (k + 0.5) / n_radial + rng.uniform(-0.07, 0.07));
      const Eigen::Vector3d q = along(t0, t1, t2, u);
      const Eigen::Vector3d n = u < 1 ? side_of(t0, t1, ys) : side_of(t1, t2, ys);
      place(q + 200.0 * n + Eigen::Vector3d(0, 0, rng.uniform(-3.0, 1.5)), -n);
    }
    // The wrist end: round the cut face at ~60 % of its half-extents, irregularly.
    for (int k = 0; k < n_wrist && ok; ++k) {
      const double th = M_PI / 2 + 2 * M_PI * k / n_wrist + rng.uniform(-0.2, 0.2), f = 0.6 + rng.uniform(-0.06, 0.06);
      place({-200.0, face_c.x() + f * face_h.x() * std::cos(th), face_c.y() + f * face_h.y() * std::sin(th)},
            Eigen::Vector3d::UnitX());
    }
    if (!ok) continue;
    for (size_t a = 0; a < c.size() && ok; ++a)
      for (size_t b = a + 1; b < c.size() && ok; ++b)
        if ((c[a] - c[b]).norm() < 2 * r + 3.0) ok = false;
    if (ok && min_signature_gap(c) >= ro.min_signature_gap_mm) markers = c;
  }
  if (markers.empty()) {
    std::string why;
    if (face_h.x() < 0.6 * section_h.x() || face_h.y() < 0.6 * section_h.y()) {
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    ": its forearm end is rounded, not sawn flat (%.0f x %.0f mm within 1 mm of the end, the forearm "
                    "%.0f x %.0f mm); saw it flat (--saw MM)",
                    2 * face_h.x(), 2 * face_h.y(), 2 * section_h.x(), 2 * section_h.y());
      why = buf;
    }
    throw InputError("--mesh",
                     "cannot place the markers on this hand's flanks and wrist end with an irregular pattern" + why);
  }

  return markers;
}

// The replica in a placement T: the hand (object 0) and its spheres (1.., the one left off
// the back scan, if any, omitted).
Scene build_scene(const std::vector<Eigen::Vector3d>& hv, const std::vector<std::array<int, 3>>& hf,
                  const std::vector<std::vector<Eigen::Vector3d>>& sphere_v, const std::vector<std::array<int, 3>>& sphere_f,
                  const Eigen::Isometry3d& T, ScanSide side, int omit_marker_in_back) {
  Scene s;
  std::vector<Eigen::Vector3d> v;
  for (const auto& p : hv) v.push_back(T * p);
  s.add(v, hf, 0);
  for (size_t k = 0; k < sphere_v.size(); ++k) {
    if (side == ScanSide::Back && static_cast<int>(k) == omit_marker_in_back) continue;
    v.clear();
    for (const auto& p : sphere_v[k]) v.push_back(T * p);
    s.add(v, sphere_f, static_cast<int>(k) + 1);
  }
  return s;
}

// The replica (hand vertices hv and its markers of radius r) turned by `base` and a random
// yaw, put at a random place on the table, resting on it.
Eigen::Isometry3d place_on_table(const std::vector<Eigen::Vector3d>& hv, const std::vector<Eigen::Vector3d>& markers,
                                 double r, const ReplicaOptions& ro, const ScannerOptions& so,
                                 const Eigen::Matrix3d& base, Rng& rng) {
  // A long replica (a large hand with a long forearm stub) fits the table only turned
  // toward its diagonal: after 200 draws within max_yaw, the yaw range widens to ±45°.
  for (int attempt = 0; attempt < 400; ++attempt) {
    const double yaw_range = attempt < 200 ? ro.max_yaw_deg : std::max(ro.max_yaw_deg, 45.0 * (attempt - 199) / 200.0);
    Eigen::Isometry3d T = yaw_then(rng.uniform(-yaw_range, yaw_range), base);
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
    for (const auto& p : hv) {
      lo = lo.cwiseMin(T * p);
      hi = hi.cwiseMax(T * p);
    }
    for (const auto& c : markers) {
      lo = lo.cwiseMin(((T * c).array() - r).matrix());
      hi = hi.cwiseMax(((T * c).array() + r).matrix());
    }
    const double margin = 3.0;
    const double x0 = margin - lo.x(), x1 = so.x_extent_mm - margin - hi.x();
    const double y0 = margin - lo.y(), y1 = so.y_extent_mm - margin - hi.y();
    if (x1 < x0 || y1 < y0) continue;
    T.pretranslate(Eigen::Vector3d(rng.uniform(x0, x1), rng.uniform(y0, y1), 0.0));
    // Rest on the table: lowest point 0.2 mm above the (possibly tilted) table top.
    double clearance = 1e9;
    for (const auto& p : hv) {
      const Eigen::Vector3d q = T * p;
      clearance = std::min(clearance, q.z() - so.table_z(q.x()));
    }
    for (const auto& c : markers) {
      const Eigen::Vector3d q = T * c;
      clearance = std::min(clearance, q.z() - r - so.table_z(q.x()));
    }
    T.pretranslate(Eigen::Vector3d(0, 0, 0.2 - clearance));
    return T;
  }
  throw InputError("--mesh", "the replica does not fit on the " + std::to_string(so.x_extent_mm) + " x " +
                                 std::to_string(so.y_extent_mm) + " mm table");
}

}  // namespace

namespace {
template <typename... Args>
std::string format(const char* f, Args... args) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, args...);
  return buf;
}
}  // namespace

void check_hand_and_rig(const Mesh& hand, const Rig& rig) {
  if (hand.vertices.empty() || hand.faces.empty()) throw InputError("--mesh", "the hand mesh has no faces");
  const Eigen::Vector3d wrist = rig.joints[joint_index("wrist").value()];
  const double length = (rig.joints[joint_index("middle-finger-tip").value()] - wrist).norm();
  constexpr double kShortest = 80, kLongest = 450;
  if (!(length >= kShortest && length <= kLongest)) {
    std::string hint;
    for (const auto& [unit, per_mm] : {std::pair<const char*, double>{"metres", 1000}, {"centimetres", 10}, {"inches", 25.4}})
      if (hint.empty() && length * per_mm >= kShortest && length * per_mm <= kLongest)
        hint = std::string("; in ") + unit + "? scale the mesh and the rig to mm (by " + format("%g", per_mm) + ")";
    throw InputError("--rig", format("its wrist lies %.4g mm from the middle fingertip: not a hand in mm (%g-%g mm)", length,
                                  kShortest, kLongest) +
                                  hint);
  }
  Eigen::AlignedBox3d box;
  for (const auto& v : hand.vertices) box.extend(v);
  const double margin = std::max(10.0, 0.05 * length);
  box.min().array() -= margin, box.max().array() += margin;
  for (size_t j = 0; j < rig.joints.size(); ++j)
    if (!box.contains(rig.joints[j]))
      throw InputError("--rig", "joint '" + std::string(joints()[j].name) +
                                    format("' lies %.0f mm outside the mesh's bounding box (widened by %.0f mm): the "
                                        "mesh and the rig are not in one frame or one unit",
                                        box.exteriorDistance(rig.joints[j]), margin));
}

ScanPair synthesize_scan_pair(const Mesh& hand_given, const Rig& rig_in, const ReplicaOptions& ro,
                              const ScannerOptions& so, std::uint64_t seed, bool verbose) {
  check_hand_and_rig(hand_given, rig_in);
  // The replica is a solid cast: an open mesh (a hole, an open wrist) has no inside to cast, and
  // its markers were refused as "an irregular pattern" that could not be placed.
  const MeshHealth health = mesh_health(hand_given);
  if (!health.closed())
    throw InputError("--mesh", "not a closed surface (" + std::to_string(health.boundary_edges) +
                                   " boundary edges): the replica is a solid cast of the hand; close the mesh's holes "
                                   "(an open wrist too) first");
  // A closed mesh whose faces face inward (its signed volume negative: another tool's winding)
  // is the same solid: its faces are turned outward, as the scanner's incidence and the true
  // skin's normals want (such a mesh was refused as a hand whose markers could not be placed).
  Mesh turned;
  if (health.volume_mm3 < 0) {
    turned = hand_given;
    for (auto& f : turned.faces) std::reverse(f.begin(), f.end());
    if (verbose) std::fprintf(stderr, "[synth scan] the mesh's faces faced inward; turned outward\n");
  }
  const Mesh& hand_in = health.volume_mm3 < 0 ? turned : hand_given;
  std::string err;
  if (!ro.IsValid(&err)) throw InputError("replica options", err);
  if (!so.IsValid(&err)) throw InputError("scanner options", err);
  Rng rng(seed);

  // Work in the hand frame.
  const Eigen::Isometry3d T_hand_rig = hand_frame_from_rig(rig_in);
  std::vector<Eigen::Vector3d> hv = hand_in.vertices;
  for (auto& p : hv) p = T_hand_rig * p;
  std::vector<std::array<int, 3>> hf = hand_in.faces;
  // The saw: the hand frame's origin is the wrist joint and its X axis the hand's long axis.
  std::optional<Mesh> sawn;  // the sawn replica's skin, hand frame
  if (ro.saw_mm) {
    sawn = saw_flat(hv, hf, *ro.saw_mm);
    hv = sawn->vertices;
    hf = sawn->faces;
  }
  RayCaster caster(hv, hf);
  Rig rig_hand = rig_in;
  for (auto& j : rig_hand.joints) j = T_hand_rig * j;
  const auto J = [&](const char* n) { return rig_hand.joints[joint_index(n).value()]; };

  std::vector<Eigen::Vector3d> markers = place_markers(hv, caster, rig_hand, rig_side(rig_in), ro, rng);
  const double r = ro.marker_radius_mm;
  // The optional plaster blob: on the back of the middle metacarpal, seen only from above.
  std::vector<Eigen::Vector3d> spheres = markers;  // the markers, then the blob if any
  if (ro.extra_bump) {
    const Eigen::Vector3d q = 0.5 * (J("wrist") + J("middle-finger-phalanx-proximal"));
    const auto hit = caster.cast({q.x(), q.y() + 6.0, 200.0}, -Eigen::Vector3d::UnitZ());
    if (!hit) throw InputError("--mesh", "cannot place the extra bump on the back of the hand");
    spheres.push_back(hit->first);
  }

  // Replica triangles in the hand frame: object 0 = hand, 1.. = markers, then the blob.
  std::vector<std::vector<Eigen::Vector3d>> sphere_v(spheres.size());
  std::vector<std::array<int, 3>> sphere_f;
  for (size_t k = 0; k < spheres.size(); ++k) icosphere(spheres[k], r, 4, &sphere_v[k], &sphere_f);

  // Placement: back up = hand +Z up, fingers toward scanner -X (the wrist end faces the
  // laser); palm up = the same turned 180° about the hand's long axis.
  const Eigen::Matrix3d R_back = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Matrix3d R_palm = R_back * Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  ScanPair out;
  out.markers_hand = markers;
  if (ro.extra_bump) out.extra_bump_hand = spheres.back();
  for (int attempt = 1; attempt <= 20; ++attempt) {
    out.placement_attempts = attempt;
    out.T_back_hand = place_on_table(hv, markers, r, ro, so, R_back, rng);
    out.T_palm_hand = place_on_table(hv, markers, r, ro, so, R_palm, rng);
    const std::uint64_t noise_seed_back = rng.next(), noise_seed_palm = rng.next();
    if (verbose) std::fprintf(stderr, "[synth scan] placement %d: scanning back side...\n", attempt);
    out.back = simulate_scan(build_scene(hv, hf, sphere_v, sphere_f, out.T_back_hand, ScanSide::Back, ro.omit_marker_in_back), so, ScanSide::Back, noise_seed_back);
    if (verbose) std::fprintf(stderr, "[synth scan] placement %d: scanning palm side...\n", attempt);
    out.palm = simulate_scan(build_scene(hv, hf, sphere_v, sphere_f, out.T_palm_hand, ScanSide::Palm, ro.omit_marker_in_back), so, ScanSide::Palm, noise_seed_palm);
    bool visible = true;
    for (size_t k = 0; k < markers.size(); ++k)
      if ((static_cast<int>(k) != ro.omit_marker_in_back &&
           out.back.returns_per_object[k + 1] < static_cast<size_t>(ro.min_marker_returns)) ||
          out.palm.returns_per_object[k + 1] < static_cast<size_t>(ro.min_marker_returns))
        visible = false;
    if (visible) {
      out.back_to_palm = out.T_palm_hand * out.T_back_hand.inverse();
      const Eigen::Isometry3d T_palm_rig = out.T_palm_hand * T_hand_rig;
      out.rig_palm = rig_in;
      out.rig_palm.frame = "palm";
      for (auto& j : out.rig_palm.joints) j = T_palm_rig * j;
      if (rig_in.palm_normal) out.rig_palm.palm_normal = (T_palm_rig.linear() * *rig_in.palm_normal).normalized();
      const SkinAlbedo albedo(rig_hand);
      out.back_photo = take_photo(out.back, so, out.T_back_hand, hv, hf, albedo);
      out.palm_photo = take_photo(out.palm, so, out.T_palm_hand, hv, hf, albedo);
      out.skin_palm = sawn ? *sawn : hand_in;
      const Eigen::Isometry3d T_palm_skin = sawn ? out.T_palm_hand : T_palm_rig;  // the sawn skin is in the hand frame
      for (Eigen::Vector3d& p : out.skin_palm.vertices) p = T_palm_skin * p;
      return out;
    }
    if (verbose) std::fprintf(stderr, "[synth scan] a marker is hidden in one scan; drawing a new placement\n");
  }
  throw InputError("--mesh", "no placement found in which every marker is visible in both scans");
}

}  // namespace handskin
