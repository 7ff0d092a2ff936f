#include "patches/layout.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <set>
#include <tuple>

#include "core/errors.hpp"
#include "mesh/triangle_tree.hpp"
#include "posture/skeleton.hpp"

namespace handskin {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kCapTilt = 1.0;  // tan of the fingertip rays' tilt toward the tip (45°)
// Two corners of a face nearer than this are refused (HandLayout::finish); a palm ring's lane
// looks past its nearest ring point for one whose corner lies farther from the level's others,
// among its kLaneCandidates nearest by angle (the palm's rings have 80 points: ~36°).
constexpr double kCornersApartMm = 0.5;
constexpr size_t kLaneCandidates = 8;

using EdgeKey = std::pair<int, int>;

// Ray casting on the skin (CGAL AABB tree): the corners are put where rays from inside a
// digit or the palm leave the skin.
class SkinCaster {
 public:
  explicit SkinCaster(const Mesh& mesh) : tt_(mesh.vertices, mesh.faces) {}
  /// Where the ray from `o` along `d` first meets the skin; with no hit (an origin outside
  /// the skin), the skin's point nearest to o + 8 d.
  Eigen::Vector3d cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
    const auto hit = tt_.tree.first_intersection(cgal::K::Ray_3(cgal::point(o), cgal::K::Vector_3(d.x(), d.y(), d.z())));
    if (hit)
      if (const auto* p = boost::get<cgal::K::Point_3>(&hit->first)) return {p->x(), p->y(), p->z()};
    return nearest(o + 8 * d.normalized());
  }
  Eigen::Vector3d nearest(const Eigen::Vector3d& q) const {
    const auto p = tt_.tree.closest_point(cgal::point(q));
    return {p.x(), p.y(), p.z()};
  }
  /// Inside the closed skin: a ray crosses it an odd number of times (a direction no face
  /// edge of a scan-aligned mesh is likely to graze).
  bool inside(const Eigen::Vector3d& o) const {
    const cgal::K::Ray_3 ray(cgal::point(o), cgal::K::Vector_3(0.5773, 0.5774, 0.5775));
    return tt_.tree.number_of_intersected_primitives(ray) % 2 == 1;
  }

 private:
  cgal::TriangleTree tt_;
};

Eigen::Vector3d orthonormal_to(const Eigen::Vector3d& v, const Eigen::Vector3d& axis) {
  return (v - v.dot(axis) * axis).normalized();
}

// Newell's normal of a closed loop (its orientation: counter-clockwise about the normal).
Eigen::Vector3d newell(const std::array<Eigen::Vector3d, 4>& loop) {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (int i = 0; i < 4; ++i) n += loop[i].cross(loop[(i + 1) % 4]);
  return n;
}

// The hand's digits and their frames from the rig's skeleton.
class DigitFrames {
 public:
  DigitFrames(const Rig& rig, const Eigen::Vector3d& radial) : skeleton_(rig), radial_(radial) {
    const Angles zero{};
    rest_ = skeleton_.positions(zero);
  }
  const Eigen::Vector3d& joint(int j) const { return rest_[j]; }
  /// The link from joint j to its child c: where flexing j moves c (toward the palm),
  /// square to the link; the dorsal direction is its opposite.
  Eigen::Vector3d dorsal(int j, int c) const {
    std::optional<int> flex;
    for (size_t k = 0; k < dofs().size(); ++k)
      if (dofs()[k].joint == j && dofs()[k].kind == DofKind::Flexion) flex = static_cast<int>(k);
    HS_CHECK(flex.has_value(), "a digit joint without flexion");
    Angles a{};
    a[*flex] = 5;
    const Eigen::Vector3d moved = skeleton_.positions(a)[c] - rest_[c];
    const Eigen::Vector3d axis = (rest_[c] - rest_[j]).normalized();
    return -orthonormal_to(moved, axis);
  }
  /// A ring of 4 directions square to `axis` at ±45° from `dorsal`: back-radial, back-ulnar,
  /// palm-ulnar, palm-radial (radial: toward the index side of the hand; for the thumb any
  /// side — its rings are matched to their neighbours').
  std::array<Eigen::Vector3d, 4> ring_directions(const Eigen::Vector3d& axis, const Eigen::Vector3d& dorsal_dir) const {
    const Eigen::Vector3d d = orthonormal_to(dorsal_dir, axis);
    Eigen::Vector3d s = axis.cross(d).normalized();
    if (s.dot(radial_) < 0) s = -s;
    return {(d + s).normalized(), (d - s).normalized(), (-d - s).normalized(), (-d + s).normalized()};
  }

 private:
  Skeleton skeleton_;
  Eigen::Vector3d radial_;
  std::array<Eigen::Vector3d, kJointCount> rest_;
};

// `next` reordered to run round its tube the way `prev` does (their Newell normals both along
// the tube's `along`, the link from the joint below to the ring's), starting at the corner
// that puts the four pairs nearest. (The rings' centres' difference, taken for `along` until
// 2026-11-25, lies nearly in the plane of a thumb's base ring — the palm's radial flank — when
// the thumb is raised and turned: the WebXR hand model's base ring then ran the other way
// round and its first row of patches crossed over, 5 mm from the skin.)
std::array<int, 4> match_ring(const std::vector<Eigen::Vector3d>& V, const std::array<int, 4>& prev,
                              std::array<int, 4> next, const Eigen::Vector3d& along) {
  auto pos = [&](const std::array<int, 4>& r) {
    std::array<Eigen::Vector3d, 4> p;
    for (int i = 0; i < 4; ++i) p[i] = V[r[i]];
    return p;
  };
  const auto P = pos(prev), N = pos(next);
  if ((newell(P).dot(along) > 0) != (newell(N).dot(along) > 0)) std::swap(next[1], next[3]);
  int best = 0;
  double bd = 1e300;
  for (int rot = 0; rot < 4; ++rot) {
    double d = 0;
    for (int i = 0; i < 4; ++i) d += (V[prev[i]] - V[next[(i + rot) % 4]]).squaredNorm();
    if (d < bd) bd = d, best = rot;
  }
  std::array<int, 4> out;
  for (int i = 0; i < 4; ++i) out[i] = next[(i + best) % 4];
  return out;
}

}  // namespace

bool PatchLayout::is_crease(int a, int b) const {
  for (const auto& c : creases)
    if ((c[0] == a && c[1] == b) || (c[0] == b && c[1] == a)) return true;
  return false;
}

void LayoutTopology::across(int f, int s, double q, int* g, int* gs, double* gq) const {
  const int h = half[f][s];
  if (neighbour[f][s] < 0) {  // a long side: the face across the half q lies in
    const int k = q < 0.5 ? 0 : 1;
    const auto& piece = halves.at({f, s})[k];
    *g = piece.first, *gs = piece.second, *gq = std::clamp(1 - 2 * q + k, 0.0, 1.0);
  } else if (h >= 0) {  // a short side: where it lies along the long one
    *g = neighbour[f][s], *gs = neighbour_side[f][s], *gq = 0.5 * h + 0.5 * (1 - q);
  } else {
    *g = neighbour[f][s], *gs = neighbour_side[f][s], *gq = 1 - q;
  }
}

std::vector<std::pair<int, int>> LayoutTopology::sides_across(int f, int s) const {
  if (neighbour[f][s] >= 0) return {{neighbour[f][s], neighbour_side[f][s]}};
  const auto& pieces = halves.at({f, s});
  return {pieces[0], pieces[1]};
}

std::vector<int> LayoutTopology::faces_across(int f) const {
  std::vector<int> out;
  for (int s = 0; s < 4; ++s)
    for (const auto& piece : sides_across(f, s)) out.push_back(piece.first);
  return out;
}

LayoutTopology layout_topology(const PatchLayout& L, const std::string& what) {
  LayoutTopology T;
  const int nf = static_cast<int>(L.faces.size());
  const int nv = static_cast<int>(L.vertices.size());
  T.neighbour.assign(nf, {-1, -1, -1, -1});
  T.neighbour_side.assign(nf, {-1, -1, -1, -1});
  T.half.assign(nf, {-1, -1, -1, -1});
  T.hangs_on.assign(nv, {-1, -1});
  T.valence.assign(nv, 0);
  std::map<EdgeKey, std::pair<int, int>> directed;
  for (int f = 0; f < nf; ++f) {
    const auto& c = L.faces[f];
    for (int s = 0; s < 4; ++s) {
      if (c[s] < 0 || c[s] >= nv)
        throw InputError(what, "face " + std::to_string(f) + " names vertex " + std::to_string(c[s]) + ", not in the layout");
      for (int t = s + 1; t < 4; ++t)
        if (c[s] == c[t]) throw InputError(what, "face " + std::to_string(f) + " repeats its corner " + std::to_string(c[s]));
      ++T.valence[c[s]];
      if (!directed.emplace(EdgeKey{c[s], c[(s + 1) % 4]}, std::make_pair(f, s)).second)
        throw InputError(what, "edge " + std::to_string(c[s]) + "-" + std::to_string(c[(s + 1) % 4]) +
                                   " is run the same way by two faces (faces not oriented alike, or more than two faces on it)");
    }
  }
  std::map<int, std::vector<int>> lone_from;  // edges run by one face only: from a vertex, their ends
  for (const auto& [e, fs] : directed) {
    const auto it = directed.find({e.second, e.first});
    if (it == directed.end()) {
      lone_from[e.first].push_back(e.second);
      continue;
    }
    T.neighbour[fs.first][fs.second] = it->second.first;
    T.neighbour_side[fs.first][fs.second] = it->second.second;
  }
  // T-junctions: three edges run by one face each, a -> b, b -> m, m -> a, are a long side and
  // its two halves. Which of the three is the long one the corners' places tell (its chord is
  // about twice the others'); topology alone cannot, as each of the three closes the other two.
  std::set<EdgeKey> used;
  size_t lone = 0;
  for (const auto& [a, ends] : lone_from) {
    lone += ends.size();
    for (const int b : ends) {
      if (used.count({a, b})) continue;
      int m = -1;
      for (const int x : lone_from.count(b) ? lone_from.at(b) : std::vector<int>{})
        if (x != a && !used.count({b, x}) && lone_from.count(x) &&
            std::count(lone_from.at(x).begin(), lone_from.at(x).end(), a) && !used.count({x, a}))
          m = x;
      if (m < 0)
        throw InputError(what, "edge " + std::to_string(a) + "-" + std::to_string(b) +
                                   " has one face only: the layout is not closed");
      used.insert({a, b}), used.insert({b, m}), used.insert({m, a});
      // The triangle's vertices in turn; (p, q) the long edge with r hanging. The hanging vertex
      // is a corner of the two faces whose short sides meet there only, where the long side's
      // ends are corners of three or more (the long side's face, a short side's, the faces
      // beyond): when exactly one of the three has two faces, it hangs. Else the longest chord
      // is the long side — a guess that fails where the long side bends or its parameter runs
      // unevenly (on a refined fixture: a long side's chord 0.93 mm, its halves' 0.35 and 1.03).
      std::array<int, 3> t = {a, b, m};
      int k = 0;
      const auto two = std::count_if(t.begin(), t.end(), [&](int x) { return T.valence[x] == 2; });
      if (two == 1) {
        for (int i = 0; i < 3; ++i)
          if (T.valence[t[(i + 2) % 3]] == 2) k = i;
      } else {
        double longest = -1;
        for (int i = 0; i < 3; ++i) {
          const double d = (L.vertices[t[i]] - L.vertices[t[(i + 1) % 3]]).squaredNorm();
          if (d > longest) longest = d, k = i;
        }
      }
      const int p = t[k], q = t[(k + 1) % 3], r = t[(k + 2) % 3];
      const auto owner = directed.at({p, q});
      const auto first = directed.at({r, p}), second = directed.at({q, r});  // across the halves from p and into q
      if (T.hangs_on[r].first >= 0)
        throw InputError(what, "vertex " + std::to_string(r) + " hangs on two sides");
      T.hangs_on[r] = owner;
      T.hanging[owner] = r;
      T.halves[owner] = {first, second};
      T.neighbour[owner.first][owner.second] = -1;
      int h = 0;
      for (const auto& piece : {first, second}) {
        T.neighbour[piece.first][piece.second] = owner.first;
        T.neighbour_side[piece.first][piece.second] = owner.second;
        T.half[piece.first][piece.second] = h++;
      }
    }
  }
  T.edges = (directed.size() - lone) / 2 + lone / 3;
  for (int v = 0; v < nv; ++v)
    if (T.hangs_on[v].first >= 0 && T.valence[v] != 2)
      throw InputError(what, "vertex " + std::to_string(v) + " hangs on a side but is a corner of " +
                                 std::to_string(T.valence[v]) + " faces, not 2");
  // Round each corner: from a face with the corner at k, its edge (v, c[k + 1]); the face
  // across its other edge (c[k − 1], v) at v comes next. A hanging vertex is not walked round.
  T.around.assign(nv, {});
  std::vector<std::pair<int, int>> first(nv, {-1, -1});
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 4; ++k)
      if (first[L.faces[f][k]].first < 0) first[L.faces[f][k]] = {f, k};
  for (int v = 0; v < nv; ++v) {
    auto [f, k] = first[v];
    if (f < 0 || T.hangs_on[v].first >= 0) continue;
    for (int step = 0; step < T.valence[v]; ++step) {
      // An edge to a vertex hanging on a long side from v is that long side: its far end.
      int end = L.faces[f][(k + 1) % 4];
      if (const auto on = T.hangs_on[end]; on.first >= 0) {
        const int a = L.faces[on.first][on.second], b = L.faces[on.first][(on.second + 1) % 4];
        if (a == v || b == v) end = a == v ? b : a;
      }
      T.around[v].push_back(end);
      int g, gs;
      double gq;
      T.across(f, (k + 3) % 4, 1.0, &g, &gs, &gq);
      int kg = -1;
      for (int q = 0; q < 4; ++q)
        if (L.faces[g][q] == v) kg = q;
      if (kg < 0) throw InputError(what, "the faces round vertex " + std::to_string(v) + " do not close into one fan");
      f = g, k = kg;
    }
    if (f != first[v].first)
      throw InputError(what, "the faces round vertex " + std::to_string(v) + " do not close into one fan");
  }
  for (int v = 0; v < nv; ++v) {
    if (T.valence[v] == 0) throw InputError(what, "vertex " + std::to_string(v) + " is in no face");
    if (T.hangs_on[v].first >= 0) T.valence[v] = 4;
  }
  return T;
}

double layout_volume(const PatchLayout& L) {
  double volume = 0;
  for (const auto& c : L.faces) {
    const auto& V = L.vertices;
    volume += V[c[0]].dot(V[c[1]].cross(V[c[2]])) + V[c[0]].dot(V[c[2]].cross(V[c[3]]));
  }
  return volume;  // six times the volume: only its sign is asked
}

void orient_layout(PatchLayout* L, const std::string& what) {
  const int nf = static_cast<int>(L->faces.size());
  if (nf == 0) throw InputError(what, "the layout has no faces");
  // Undirected edge → faces on it; then a breadth-first walk turning each face to run every
  // shared edge the other way from the face it was reached from.
  std::map<EdgeKey, std::vector<std::pair<int, int>>> on_edge;
  for (int f = 0; f < nf; ++f)
    for (int s = 0; s < 4; ++s) {
      const int a = L->faces[f][s], b = L->faces[f][(s + 1) % 4];
      on_edge[{std::min(a, b), std::max(a, b)}].push_back({f, s});
    }
  for (const auto& [e, fs] : on_edge)
    if (fs.size() != 2)
      throw InputError(what, "edge " + std::to_string(e.first) + "-" + std::to_string(e.second) + " has " +
                                 std::to_string(fs.size()) + " faces, not 2: the layout is not a closed surface");
  auto runs = [&](int f, int a, int b) {
    for (int s = 0; s < 4; ++s)
      if (L->faces[f][s] == a && L->faces[f][(s + 1) % 4] == b) return true;
    return false;
  };
  std::vector<char> done(nf, 0);
  std::vector<int> queue;
  for (int seed = 0; seed < nf; ++seed) {
    if (done[seed]) continue;
    done[seed] = 1;
    queue.assign(1, seed);
    for (size_t q = 0; q < queue.size(); ++q) {
      const int f = queue[q];
      for (int s = 0; s < 4; ++s) {
        const int a = L->faces[f][s], b = L->faces[f][(s + 1) % 4];
        for (const auto& [g, gs] : on_edge[{std::min(a, b), std::max(a, b)}]) {
          if (g == f) continue;
          const bool same_way = runs(g, a, b);
          if (done[g]) {
            if (same_way) throw InputError(what, "the layout cannot be oriented (a one-sided surface)");
            continue;
          }
          if (same_way) std::reverse(L->faces[g].begin(), L->faces[g].end());
          done[g] = 1;
          queue.push_back(g);
        }
      }
    }
  }
  // Outward: the enclosed volume positive.
  if (layout_volume(*L) < 0)
    for (auto& c : L->faces) std::reverse(c.begin(), c.end());
}

PatchLayout subdivide_layout(const PatchLayout& L, int k) {
  HS_CHECK(k >= 1, "subdivision must be at least 1");
  if (k == 1) return L;
  PatchLayout out;
  out.vertices = L.vertices;
  std::map<std::tuple<int, int, int>, int> edge_point;  // (lower corner, higher corner, steps from the lower)
  auto at = [&](const std::array<int, 4>& c, int i, int j) -> int {
    // Grid point (i, j) of a face, i along corner 0 → 1, j along corner 0 → 3.
    if ((i == 0 || i == k) && (j == 0 || j == k)) return c[i == 0 ? (j == 0 ? 0 : 3) : (j == 0 ? 1 : 2)];
    const auto& V = L.vertices;
    const double s = static_cast<double>(i) / k, t = static_cast<double>(j) / k;
    const Eigen::Vector3d p = (1 - s) * (1 - t) * V[c[0]] + s * (1 - t) * V[c[1]] + s * t * V[c[2]] + (1 - s) * t * V[c[3]];
    int a = -1, b = -1, step = 0;
    if (j == 0) a = c[0], b = c[1], step = i;
    else if (i == k) a = c[1], b = c[2], step = j;
    else if (j == k) a = c[3], b = c[2], step = i;
    else if (i == 0) a = c[0], b = c[3], step = j;
    if (a < 0) {
      out.vertices.push_back(p);
      return static_cast<int>(out.vertices.size()) - 1;
    }
    if (a > b) std::swap(a, b), step = k - step;
    const auto [it, fresh] = edge_point.emplace(std::make_tuple(a, b, step), static_cast<int>(out.vertices.size()));
    if (fresh) out.vertices.push_back(p);
    return it->second;
  };
  auto edge_vertex = [&](int a, int b, int step) {  // step k / k along a → b
    if (step == 0) return a;
    if (step == k) return b;
    if (a > b) std::swap(a, b), step = k - step;
    return edge_point.at(std::make_tuple(a, b, step));
  };
  for (size_t f = 0; f < L.faces.size(); ++f) {
    std::vector<int> g(static_cast<size_t>(k + 1) * (k + 1));
    for (int i = 0; i <= k; ++i)
      for (int j = 0; j <= k; ++j) g[i * (k + 1) + j] = at(L.faces[f], i, j);
    for (int i = 0; i < k; ++i)
      for (int j = 0; j < k; ++j) {
        out.faces.push_back({g[i * (k + 1) + j], g[(i + 1) * (k + 1) + j], g[(i + 1) * (k + 1) + j + 1], g[i * (k + 1) + j + 1]});
        out.names.push_back((f < L.names.size() ? L.names[f] : "face" + std::to_string(f)) + "." + std::to_string(i) +
                            std::to_string(j));
        if (!L.levels.empty()) out.levels.push_back(L.levels[f]);
      }
  }
  for (const auto& e : L.creases)
    for (int step = 0; step < k; ++step) out.creases.push_back({edge_vertex(e[0], e[1], step), edge_vertex(e[0], e[1], step + 1)});
  return out;
}

namespace {

// The hand's layout, built step by step (hand_patch_layout runs them): the skin, the rig and
// the hand's axes at hand, the layout growing in L.
class HandLayout {
 public:
  HandLayout(const SkinResult& skin, const Rig& rig, const std::vector<Eigen::Vector3d>& points,
             const std::vector<std::uint32_t>& sides)
      : skin_(skin), rig_(rig), caster(skin.mesh), hand(hand_frame_from_rig(rig)), x(hand.linear().row(0).transpose()),
        n(dorsal_axis(hand, points, sides)),
        radial(orthonormal_to(rig.joints[J(Finger::Index, 1)] - rig.joints[J(Finger::Little, 1)], x)),
        frames(rig, radial), to_rig(hand.inverse()) {}

  /// 1. The webs between the fingers (a corner on the back and one on the palm) and the
  /// index's and the little finger's outer flanks at their level.
  void webs();
  /// 2. The palm's rings: the wrist rim, two between (the second where the thumb's base ends,
  /// moved by `thumb_ring_shift` rings; the thumb's base turned by `thumb_turn_deg`), the webs' ring.
  void palm_rings(int thumb_ring_shift, double thumb_turn_deg);
  /// 3. The palm's faces, the wrist's cap and the rim's creases.
  void palm_faces();
  /// 4. Each digit: a base ring, rings at the joints and one on the distal link, a cap.
  void digits();
  /// 5. Checked (no face with coinciding corners) and oriented.
  PatchLayout finish();

 private:
  static int J(Finger f, int level) { return finger_chain(f)[level]; }
  // The hand's dorsal axis: out of the back (the back scan's points lie that way from the
  // palm scan's).
  static Eigen::Vector3d dorsal_axis(const Eigen::Isometry3d& hand, const std::vector<Eigen::Vector3d>& points,
                                     const std::vector<std::uint32_t>& sides) {
    Eigen::Vector3d n = hand.linear().row(2).transpose();
    double back = 0, palm_side = 0;
    size_t nb = 0, np = 0;
    for (size_t k = 0; k < points.size(); ++k)
      (sides[k] == 1 ? back : palm_side) += points[k].dot(n), ++(sides[k] == 1 ? nb : np);
    if (nb > 0 && np > 0 && back / nb < palm_side / np) n = -n;
    return n;
  }
  int add(const Eigen::Vector3d& p) {
    L.vertices.push_back(p);
    return static_cast<int>(L.vertices.size()) - 1;
  }
  // Where a ray from inside digit `f` at `o` along `dir` leaves the digit's own skin. The
  // digit's flesh opens into the palm's and into its webs, so a ray from a joint near them
  // (a raised, turned thumb's MCP: its dorsal-ulnar ray points into the hand or the web to
  // the index) can run on through the palm and leave it 20-60 mm away (the WebXR hand model,
  // scripts/webxr_study.py). The digit's own section there is the ring of the skin's ring
  // grid nearest `o`: where the ray's direction, taken in that ring's plane from its centre,
  // crosses the ring. A hit more than 3 mm beyond that crossing is replaced by it (put on the
  // skin).
  Eigen::Vector3d digit_cast(Finger f, const Eigen::Vector3d& o, const Eigen::Vector3d& dir) const {
    const SkinResult& skin = skin_;
    const Eigen::Vector3d hit = caster.cast(o, dir);
    const RingGrid& g = skin.grid.at(static_cast<int>(SkinTube::Thumb) + static_cast<int>(f));
    const std::vector<Eigen::Vector3d>* ring = nullptr;
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    double best = 1e300;
    for (const auto& r : g.rings) {
      if (r.size() < 3) continue;
      Eigen::Vector3d m = Eigen::Vector3d::Zero();
      for (const auto& p : r) m += p;
      m /= static_cast<double>(r.size());
      if ((m - o).squaredNorm() < best) best = (m - o).squaredNorm(), c = m, ring = &r;
    }
    if (ring == nullptr) return hit;
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // Newell's, of the ring
    for (size_t k = 0; k < ring->size(); ++k) normal += ((*ring)[k] - c).cross((*ring)[(k + 1) % ring->size()] - c);
    if (normal.norm() < 1e-9) return hit;
    normal.normalize();
    const Eigen::Vector3d e1 = dir - dir.dot(normal) * normal;
    if (e1.norm() < 0.3) return hit;  // the ray runs along the digit: no crossing to compare with
    const Eigen::Vector3d u = e1.normalized(), v = normal.cross(u);
    std::optional<Eigen::Vector3d> cross;
    double reach = 0;
    for (size_t k = 0; k < ring->size(); ++k) {
      const Eigen::Vector3d& a = (*ring)[k];
      const Eigen::Vector3d& b = (*ring)[(k + 1) % ring->size()];
      const double ya = (a - c).dot(v), yb = (b - c).dot(v);
      if ((ya > 0) == (yb > 0) || ya == yb) continue;
      const Eigen::Vector3d q = a + ya / (ya - yb) * (b - a);
      if ((q - c).dot(u) > reach) reach = (q - c).dot(u), cross = q;
    }
    // Beyond 1.5 × the digit's median section radius a corner is not on the digit's own
    // section either way: then the skin's point nearest to one radius out along the ray.
    const double radius = skin.tubes[static_cast<int>(SkinTube::Thumb) + static_cast<int>(f)].section_radius_mm;
    const double limit = radius > 0 ? 1.5 * radius : 1e300;
    if ((hit - o).norm() <= limit && (!cross || (hit - o).norm() <= (*cross - o).norm() + 3.0)) return hit;
    if (cross && (*cross - o).norm() <= limit) return caster.nearest(*cross);
    return caster.nearest(o + (radius > 0 ? radius : 1.0) * dir.normalized());
  }
  // A digit's ring of four corners at `o` (square to `axis`, ±45° from `dorsal`).
  std::array<int, 4> digit_ring(Finger f, const Eigen::Vector3d& o, const Eigen::Vector3d& axis,
                                const Eigen::Vector3d& dorsal) {
    std::array<int, 4> r;
    const auto dirs = frames.ring_directions(axis, dorsal);
    for (int i = 0; i < 4; ++i) r[i] = add(digit_cast(f, o, dirs[i]));
    return r;
  }
  // The index's radial flank and the little finger's ulnar flank at their webs' level.
  void flank(Finger f, const Eigen::Vector3d& web, bool radial_side, int* b, int* p) {
    const Eigen::Vector3d a = frames.joint(J(f, 1)), c = frames.joint(J(f, 2));
    const Eigen::Vector3d u = (c - a).normalized();
    const double t = std::clamp((web - a).dot(u) / (c - a).norm(), 0.0, 0.9);
    const auto dirs = frames.ring_directions(u, frames.dorsal(J(f, 1), J(f, 2)));
    const Eigen::Vector3d o = a + t * (c - a);
    *b = add(caster.cast(o, radial_side ? dirs[0] : dirs[1]));
    *p = add(caster.cast(o, radial_side ? dirs[3] : dirs[2]));
  }
  // On a ring of the palm's grid, the section's centre and half-extents along radial and n.
  void section(const std::vector<Eigen::Vector3d>& ring, Eigen::Vector3d* c, double* A, double* B) const {
    *c = Eigen::Vector3d::Zero();
    for (const auto& p : ring) *c += p;
    *c /= static_cast<double>(ring.size());
    *A = *B = 1e-9;
    for (const auto& p : ring) *A = std::max(*A, std::abs((p - *c).dot(radial))), *B = std::max(*B, std::abs((p - *c).dot(n)));
  }
  // A point's angle on a section scaled to a unit circle (0 radial, 90° dorsal, ±180° ulnar).
  double angle_of(const Eigen::Vector3d& p, const Eigen::Vector3d& c, double A, double B) const {
    return std::atan2((p - c).dot(n) / B, (p - c).dot(radial) / A);
  }
  // One digit from its base ring.
  void digit(Finger f, std::array<int, 4> base);
  std::array<int, 10> loop(int level) const {
    std::array<int, 10> l;
    for (int k = 0; k < 5; ++k) l[k] = pb[level][k], l[9 - k] = pp[level][k];
    return l;
  }

  const SkinResult& skin_;
  const Rig& rig_;
  const SkinCaster caster;
  const Eigen::Isometry3d hand;
  const Eigen::Vector3d x, n, radial;
  const DigitFrames frames;
  const Eigen::Isometry3d to_rig;
  static constexpr Finger fingers[4] = {Finger::Index, Finger::Middle, Finger::Ring, Finger::Little};
  std::array<int, 5> web_b{}, web_p{};
  std::array<std::array<int, 5>, 4> pb{}, pp{};  ///< the palm's rings' corners, back and palm
  PatchLayout L;
};

void HandLayout::webs() {
  const SkinResult& skin = skin_;
  for (int k = 1; k <= 3; ++k) {
    const Finger f1 = fingers[k - 1], f2 = fingers[k];
    const Eigen::Vector3d w = to_rig * skin.webs[k - 1];
    const Eigen::Vector3d u =
        ((frames.joint(J(f1, 2)) - frames.joint(J(f1, 1))).normalized() + (frames.joint(J(f2, 2)) - frames.joint(J(f2, 1))).normalized())
            .normalized();
    const Eigen::Vector3d d = orthonormal_to(frames.dorsal(J(f1, 1), J(f1, 2)) + frames.dorsal(J(f2, 1), J(f2, 2)), u);
    // From inside the web's flesh, a little proximal of where the web ends, and where the
    // flesh is at least 2 mm thick along the rays: on curled fingers the web's sheet can be
    // so thin 3 mm in that the back's and the palm's corners came out 0.3 mm apart (the
    // WebXR hand model curled, scripts/webxr_study.py), a face with no area.
    Eigen::Vector3d hb, hp;
    for (double back = 3; back <= 15; back += 3) {
      const Eigen::Vector3d o = w - back * u;
      if (!caster.inside(o) && back < 15) continue;
      hb = caster.cast(o, d), hp = caster.cast(o, -d);
      if ((hb - hp).norm() >= 2.0) break;
    }
    web_b[k] = add(hb);
    web_p[k] = add(hp);
  }
  flank(Finger::Index, to_rig * skin.webs[0], true, &web_b[0], &web_p[0]);
  flank(Finger::Little, to_rig * skin.webs[2], false, &web_b[4], &web_p[4]);
}

void HandLayout::palm_rings(int thumb_ring_shift, double thumb_turn_deg) {
  const RingGrid& palm = skin_.grid.at(static_cast<int>(SkinTube::Palm));
  // On a ring of the palm's grid, a corner at angle θ of the section scaled to a unit circle
  // (0 radial, 90° dorsal, ±180° ulnar): the lanes run from the wrist's even spread to the
  // webs' corners.
  pb[3] = web_b, pp[3] = web_p;
  std::array<double, 5> top_b, top_p;
  {
    Eigen::Vector3d c;
    double A, B;
    section(palm.rings.back(), &c, &A, &B);
    for (int k = 0; k < 5; ++k) top_b[k] = angle_of(L.vertices[web_b[k]], c, A, B), top_p[k] = angle_of(L.vertices[web_p[k]], c, A, B);
  }
  const size_t nr = palm.rings.size();
  for (int level = 0; level < 3; ++level) {
    // Level 2 (where the thumb's base ends) moved by `thumb_ring_shift`, kept 2 rings clear of
    // level 1 and of the webs' ring.
    long at = static_cast<long>(level * (nr - 1) / 3);
    if (level == 2 && thumb_ring_shift != 0) {
      const long lo = static_cast<long>(nr - 1) / 3 + 2, hi = static_cast<long>(nr) - 3;
      if (lo <= hi) at = std::clamp(at + thumb_ring_shift, lo, hi);
    }
    const auto& ring = palm.rings[static_cast<size_t>(at)];
    Eigen::Vector3d c;
    double A, B;
    section(ring, &c, &A, &B);
    std::vector<double> th(ring.size());
    for (size_t i = 0; i < ring.size(); ++i) th[i] = angle_of(ring[i], c, A, B);
    const double f = level / 3.0;
    std::array<double, 5> tb, tp;
    // A back corner stays on the back (5°–175°), a palm corner on the palm (−175°–−5°).
    const auto on_back = [](double t) { return std::clamp(t, 5 * kPi / 180, 175 * kPi / 180); };
    const auto on_palm = [](double t) { return std::clamp(t, -175 * kPi / 180, -5 * kPi / 180); };
    for (int k = 0; k < 5; ++k) {
      const double even = (45 + 22.5 * k) * kPi / 180;
      tb[k] = on_back(even + f * std::remainder(top_b[k] - even, 2 * kPi));
      tp[k] = on_palm(-even + f * std::remainder(top_p[k] + even, 2 * kPi));
    }
    // Levels 1 and 2 (the thumb's base between them): the base's corners on the back (b0) and
    // the palm (p0) turned `thumb_turn_deg` round the section toward the palm, where a thumb
    // turned under the hand grows from the palm's side and not from its radial flank.
    if (level == 1 || level == 2) {
      const double turn = thumb_turn_deg * kPi / 180;
      tb[0] = on_back(tb[0] - turn);
      tp[0] = on_palm(tp[0] - turn);
    }
    std::sort(tb.begin(), tb.end());
    std::sort(tp.begin(), tp.end(), std::greater<double>());
    // Round the loop b0…b4 p4…p0 the angles increase: each lane takes the ring point nearest
    // its angle among those no earlier lane took, so that no two corners coincide however the
    // section is shaped. Two ring points can still meet the skin at one place where the ring
    // runs inside the thumb's tube (the union left that stretch of the palm's ring in the
    // thenar): R06 of `scripts/random_hands_study.py --draw 76` (its thumb spread 59°) put the
    // level's two palm-side corners 0.5 mm apart, and the layout was refused. A lane whose
    // nearest ring point meets the skin within kCornersApartMm of a corner this level placed
    // takes the next nearest by angle that does not, of its kLaneCandidates nearest (the first,
    // if none: finish() refuses it).
    std::vector<char> taken(ring.size(), 0);
    std::vector<Eigen::Vector3d> placed;
    auto at_angle = [&](double target) {
      std::vector<std::pair<double, size_t>> by_angle;
      for (size_t i = 0; i < ring.size(); ++i)
        if (!taken[i]) by_angle.push_back({std::abs(std::remainder(th[i] - target, 2 * kPi)), i});
      std::sort(by_angle.begin(), by_angle.end());
      HS_CHECK(!by_angle.empty(), "a palm ring has fewer points than the layout's lanes");
      const auto apart = [&](const Eigen::Vector3d& p) {
        return std::none_of(placed.begin(), placed.end(), [&](const Eigen::Vector3d& q) { return (p - q).norm() < kCornersApartMm; });
      };
      size_t best = by_angle.front().second;
      Eigen::Vector3d at = caster.nearest(ring[best]);
      for (size_t k = 1; k < std::min(by_angle.size(), kLaneCandidates) && !apart(at); ++k) {
        const Eigen::Vector3d next = caster.nearest(ring[by_angle[k].second]);
        if (apart(next)) best = by_angle[k].second, at = next;
      }
      taken[best] = 1;
      placed.push_back(at);
      return add(at);
    };
    for (int k = 0; k < 5; ++k) pb[level][k] = at_angle(tb[k]);
    for (int k = 4; k >= 0; --k) pp[level][k] = at_angle(tp[k]);
  }
}

void HandLayout::palm_faces() {
  // Palm faces: 10 columns round the loop b0…b4 p4…p0, 3 rows; the thumb grows from the
  // radial flank's middle row.
  const char* column_name[10] = {"back0", "back1", "back2", "back3", "ulnar", "palm3", "palm2", "palm1", "palm0", "radial"};
  for (int level = 0; level < 3; ++level) {
    const auto lo = loop(level), hi = loop(level + 1);
    for (int c = 0; c < 10; ++c) {
      if (level == 1 && c == 9) continue;
      L.faces.push_back({lo[c], lo[(c + 1) % 10], hi[(c + 1) % 10], hi[c]});
      L.names.push_back("palm." + std::to_string(level) + "." + column_name[c]);
    }
  }
  for (int k = 0; k < 4; ++k) {
    L.faces.push_back({pb[0][k], pb[0][k + 1], pp[0][k + 1], pp[0][k]});
    L.names.push_back("wrist." + std::to_string(k));
  }
  // The cut is sawn square across the cast: its rim is a sharp edge, not a smooth join.
  {
    const auto rim = loop(0);
    for (int c = 0; c < 10; ++c) L.creases.push_back({rim[c], rim[(c + 1) % 10]});
  }
}

void HandLayout::digit(Finger f, std::array<int, 4> base) {
  static const char* side_name[4] = {"back", "ulnar", "palm", "radial"};
  const auto chain = finger_chain(f);
  const int tip = chain.back(), distal = chain[chain.size() - 2];
  std::vector<std::array<int, 4>> rings = {base};
  // The joints past the base: MCP (the thumb), PIP and DIP (fingers; the thumb's IP).
  const size_t first = f == Finger::Thumb ? 1 : 2;
  for (size_t i = first; i + 1 < chain.size(); ++i) {
    const int j = chain[i];
    const Eigen::Vector3d in = (frames.joint(j) - frames.joint(chain[i - 1])).normalized();
    const Eigen::Vector3d out = (frames.joint(chain[i + 1]) - frames.joint(j)).normalized();
    const Eigen::Vector3d axis = (in + out).normalized();
    const Eigen::Vector3d d = frames.dorsal(chain[i - 1], j) + frames.dorsal(j, chain[i + 1]);
    rings.push_back(match_ring(L.vertices, rings.back(), digit_ring(f, frames.joint(j), axis, d),
                               frames.joint(j) - frames.joint(chain[i - 1])));
  }
  // The fingertip's ring is drawn forward over the dome (rays 45° toward the tip), so that
  // the cap and the last row's patches meet at about 120° each at its corners, as three
  // patches round a point of a smooth surface should (a ring square to the axis would
  // leave the cap a straight angle at each corner and no normal there).
  const Eigen::Vector3d a = frames.joint(distal), b = frames.joint(tip);
  const Eigen::Vector3d axis = (b - a).normalized();
  std::array<int, 4> cap;
  {
    const auto dirs = frames.ring_directions(axis, frames.dorsal(distal, tip));
    const Eigen::Vector3d o = a + 0.5 * (b - a);
    for (int i = 0; i < 4; ++i) cap[i] = add(digit_cast(f, o, (dirs[i] + kCapTilt * axis).normalized()));
  }
  rings.push_back(match_ring(L.vertices, rings.back(), cap, b - a));
  const std::string name = finger_dof_name(f);
  for (size_t r = 0; r + 1 < rings.size(); ++r)
    for (int i = 0; i < 4; ++i) {
      L.faces.push_back({rings[r][i], rings[r][(i + 1) % 4], rings[r + 1][(i + 1) % 4], rings[r + 1][i]});
      L.names.push_back(name + "." + std::to_string(r) + "." + side_name[i]);
    }
  L.faces.push_back(rings.back());
  L.names.push_back(name + ".tip");
}

void HandLayout::digits() {
  digit(Finger::Thumb, {pb[1][0], pb[2][0], pp[2][0], pp[1][0]});
  for (int k = 0; k < 4; ++k) digit(fingers[k], {web_b[k], web_b[k + 1], web_p[k + 1], web_p[k]});
}

PatchLayout HandLayout::finish() {
  // Corners that coincide (two rays meeting the skin at one place) would leave a face with no
  // area: refused rather than fitted.
  for (size_t f = 0; f < L.faces.size(); ++f)
    for (int s = 0; s < 4; ++s)
      if ((L.vertices[L.faces[f][s]] - L.vertices[L.faces[f][(s + 1) % 4]]).norm() < kCornersApartMm)
        throw InputError("patches", "the patch layout's face " + L.names[f] +
                                        " has two corners within 0.5 mm of each other; the rig may not fit this skin");
  orient_layout(&L, "patch layout");
  return std::move(L);
}

}  // namespace

PatchLayout hand_patch_layout(const SkinResult& skin, const Rig& rig, const std::vector<Eigen::Vector3d>& points,
                              const std::vector<std::uint32_t>& sides, int thumb_ring_shift, double thumb_turn_deg) {
  for (int t = 0; t < kSkinTubes; ++t)
    if (t >= static_cast<int>(skin.tubes.size()) || !skin.tubes[t].present)
      throw InputError("patches", std::string("the ") + skin_tube_name(t) +
                                      " is missing from the skin; the patch layout needs the palm and all five digits");
  if (skin.grid.at(static_cast<int>(SkinTube::Palm)).rings.size() < 4 || skin.webs.size() != 3)
    throw InputError("patches", "the skin has too few palm rings or webs to lay patches on");
  HandLayout h(skin, rig, points, sides);
  h.webs();
  h.palm_rings(thumb_ring_shift, thumb_turn_deg);
  h.palm_faces();
  h.digits();
  return h.finish();
}

}  // namespace handskin
