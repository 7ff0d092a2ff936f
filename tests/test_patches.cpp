// Bézier patches (issue 13): a closed quad layout with exact borders, a fit that reaches the
// data, the parameter correction, layouts checked and given back, the command's files.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <random>
#include <set>
#include <tuple>

#include <Eigen/Geometry>

#include "core/atomic_file.hpp"
#include "core/json_util.hpp"
#include "core/png_io.hpp"
#include "pipeline/layout_json.hpp"
#include "mesh/mesh_distance.hpp"
#include "mesh/point_grid.hpp"
#include "patches/patch_steps.hpp"
#include "patches/patches.hpp"
#include "pipeline/options.hpp"
#include "pipeline/patch_report.hpp"
#include "pipeline/patch_stage.hpp"
#include "pipeline/skin_stage.hpp"
#include "pipeline/stage_options.hpp"
#include "register/registration.hpp"
#include "test_util.hpp"

using namespace handskin;
namespace fs = std::filesystem;

namespace {
// An ellipsoid of known shape (radii 30, 20, 15 mm) and a cube layout on it, split 3 × 3:
// 54 patches, eight corners where three meet.
const Eigen::Vector3d kRadii(30, 20, 15);
Eigen::Vector3d ellipsoid_point(const Eigen::Vector3d& dir) {  // the ray from the centre along dir meets it here
  const Eigen::Vector3d u = dir.normalized();
  return u / u.cwiseProduct(kRadii.cwiseInverse()).norm();
}
Eigen::Vector3d ellipsoid_normal(const Eigen::Vector3d& p) {
  return p.cwiseProduct(kRadii.cwiseAbs2().cwiseInverse()).normalized();
}

PatchLayout cube_layout(int k) {
  PatchLayout L;
  for (int i = 0; i < 8; ++i) L.vertices.push_back(ellipsoid_point(Eigen::Vector3d(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1)));
  L.faces = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (int f = 0; f < 6; ++f) L.names.push_back("cube" + std::to_string(f));
  orient_layout(&L, "cube");
  return subdivide_layout(L, k);
}

struct Cloud {
  std::vector<Eigen::Vector3d> points;
  std::vector<std::uint32_t> sides;
};
Cloud ellipsoid_cloud(size_t n, double noise) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> N(0, 1);
  Cloud c;
  for (size_t k = 0; k < n; ++k) {
    const Eigen::Vector3d p = ellipsoid_point(Eigen::Vector3d(N(rng), N(rng), N(rng)));
    c.points.push_back(p + noise * N(rng) * ellipsoid_normal(p));
    c.sides.push_back(p.z() > 0 ? 1 : 0);
  }
  return c;
}
}  // namespace

TEST(Patches, AClosedSurfaceOfKnownShapeIsFittedWithExactBordersAndSmoothJoins) {
  const PatchLayout L = cube_layout(3);
  const Cloud c = ellipsoid_cloud(40000, 0.01);
  const PatchSkin s = fit_patches(L, c.points, c.sides, {}, {}, PatchOptions{});
  ASSERT_EQ(s.patches.size(), 54u);
  EXPECT_EQ(s.irregular_corners, 8);
  EXPECT_EQ(s.control_points, L.vertices.size() + 2 * 108 + 4 * 54);  // corners, 2 per edge, 4 per face
  EXPECT_LT(s.g0_gap_mm, 1e-9);  // shared control points: the same curve from both sides
  EXPECT_LT(s.g1_median_deg, 0.5);
  // G1 along the borders into the eight corners too: measured p95 0.08°, at most 0.20° next to
  // the corners (0.70° and 1.44° with those borders held C1 only away from the corners).
  EXPECT_LT(s.g1_p95_deg, 0.3);
  EXPECT_LT(s.g1_near_max_deg, 0.6);
  for (int side = 0; side < 2; ++side) {
    EXPECT_GT(s.side[side].points, 15000u);
    EXPECT_LT(s.side[side].mean, 0.012) << side;  // noise 0.01 mm: its mean |n| is 0.008; measured 0.009
    EXPECT_LT(s.side[side].max, 0.1) << side;     // measured 0.045
  }
  // The correction lowers the error from the first fit's.
  ASSERT_GE(s.rms_per_round.size(), 2u);
  EXPECT_LT(s.rms_per_round.back(), s.rms_per_round.front());
  // The surface kept is the round's with the lowest RMS.
  ASSERT_GE(s.kept_round, 0);
  ASSERT_LT(s.kept_round, static_cast<int>(s.rms_per_round.size()));
  EXPECT_EQ(s.rms_per_round[s.kept_round], *std::min_element(s.rms_per_round.begin(), s.rms_per_round.end()));
  // The surface itself is the ellipsoid: its tessellation's vertices lie on it.
  const Mesh m = tessellate(s, 6);
  double worst = 0;
  for (const Eigen::Vector3d& p : m.vertices) {
    worst = std::max(worst, (p - ellipsoid_point(p)).norm());
  }
  EXPECT_LT(worst, 0.1);
  // Closed, one piece, outward, no cracks: every edge shared by two triangles.
  const MeshHealth h = mesh_health(m);
  EXPECT_EQ(h.boundary_edges, 0u);
  EXPECT_EQ(h.nonmanifold_vertices, 0u);
  EXPECT_EQ(h.components, 1u);
  EXPECT_GT(h.volume_mm3, 0.95 * 4.0 / 3.0 * M_PI * 30 * 20 * 15);
  // Every border of every patch equals its neighbour's, bit for bit, run the other way.
  const LayoutTopology T = layout_topology(s.layout, "cube");
  auto border = [](const BezierPatch& p, int side, int k) {  // k-th control point along side
    const int i[4] = {k, 3, 3 - k, 0}, j[4] = {0, k, 3, 3 - k};
    return p.P[4 * i[side] + j[side]];
  };
  for (size_t f = 0; f < s.patches.size(); ++f)
    for (int side = 0; side < 4; ++side)
      for (int k = 0; k < 4; ++k)
        ASSERT_EQ(border(s.patches[f], side, k), border(s.patches[T.neighbour[f][side]], T.neighbour_side[f][side], 3 - k));
  // Its report page needs no run around it: without a run's report (gates, stages) those
  // sections are left out, not read from nothing.
  PatchStageResult page;
  page.patches = s;
  page.tessellation = m;
  const std::string html = patch_report_html(page);
  EXPECT_NE(html.find("Table 4.1"), std::string::npos);
  EXPECT_EQ(html.find("Quality gates"), std::string::npos);
  EXPECT_EQ(html.find("The run"), std::string::npos);
  EXPECT_NE(patch_report_html(page, Json{{"gates", Json::array()}}).find("Quality gates"), std::string::npos);
}

// Refinement to a tolerance (issue 38): a split stays local, leaving T-junctions whose short
// sides are the long side's halves exactly (G0), but beside a corner where other than four
// patches meet; the split surface is the same surface (de Casteljau); the refit keeps its
// borders exact, its tessellation closed, and fits no worse; with a tolerance the fit splits
// only where the points miss.
TEST(Patches, SplitsStayLocalWithExactTJunctionsAndKeepTheSurface) {
  const PatchLayout L = cube_layout(3);  // 54 patches; the middle one of each cube face touches no cube corner
  const Cloud c = ellipsoid_cloud(40000, 0.01);
  const PatchSkin s = fit_patches(L, c.points, c.sides, {}, {}, PatchOptions{});
  const LayoutTopology T = layout_topology(s.layout, "cube");
  // The middle face of a cube face cut at u = 1/2: only it is cut (its split sides lie against
  // unsplit faces: two T-junctions), not the strip of 12 round the cube.
  int middle = -1;
  for (size_t f = 0; f < s.patches.size(); ++f)
    if (s.layout.names[f] == "cube0.11") middle = static_cast<int>(f);
  ASSERT_GE(middle, 0);
  std::vector<int> cuts(s.patches.size(), 0);
  cuts[middle] = kCutU;
  cuts = balance_cuts(s.layout, T, cuts);
  EXPECT_EQ(std::count_if(cuts.begin(), cuts.end(), [](int k) { return k != 0; }), 1);
  {
    const LayoutSplit one = split_layout(s, cuts);
    const LayoutTopology T1 = layout_topology(one.layout, "split cube");
    EXPECT_EQ(T1.halves.size(), 2u);  // the faces across its sides 0 and 2 keep them whole
    // The hanging vertex is told by its two faces, not by the chords: a long side that bends
    // (or whose parameter runs unevenly) can be shorter than a half's chord. A refined fixture
    // layout had one (chords 0.93 mm against 0.35 and 1.03) and was refused, the longest chord
    // naming a corner of four faces as hanging.
    for (const auto& [long_side, r] : T1.hanging) {
      PatchLayout bent = one.layout;
      bent.vertices[r] += 10.0 * (bent.vertices[r] - Eigen::Vector3d::Zero());
      LayoutTopology Tb;
      ASSERT_NO_THROW(Tb = layout_topology(bent, "bent"));
      EXPECT_EQ(Tb.hangs_on[r], long_side);
    }
    const PatchSkin r = fit_patches(one.layout, c.points, c.sides, {}, {}, PatchOptions{}, &one.seed);
    EXPECT_LT(r.g0_gap_mm, 1e-9);  // measured along every short side against its long side
    EXPECT_LE(r.side[0].mean, s.side[0].mean * 1.05);
    EXPECT_LT(r.g1_max_deg, 1.0);  // C1 across the T-junctions weighs the halved face's slower parameter
    int derived = 0;
    for (const auto& d : r.control_derived) derived += !d.empty();
    EXPECT_EQ(derived, 2 * 5);  // per T-junction the hanging corner and the short sides' 4 edge points
    // The tessellation is closed: the long sides carry the short sides' points.
    const Mesh m = tessellate(r, 4);
    const MeshHealth h = mesh_health(m);
    EXPECT_EQ(h.boundary_edges, 0u);
    EXPECT_EQ(h.nonmanifold_vertices, 0u);
    // Posed or not, the short sides stay the long sides' halves (rebuild_patches derives them).
    PatchSkin moved = r;
    for (auto& q : moved.control) q += Eigen::Vector3d(0.1 * q.y(), 0, 0.05 * q.x());
    rebuild_patches(&moved);
    const LayoutTopology Tr = layout_topology(moved.layout, "moved");
    for (const auto& [long_side, pieces] : Tr.halves)
      for (int h2 = 0; h2 < 2; ++h2)
        for (double q : {0.2, 0.7}) {
          int g, gs;
          double gq;
          Tr.across(pieces[h2].first, pieces[h2].second, q, &g, &gs, &gq);
          const Eigen::Vector2d a = patch_steps::on_side(pieces[h2].second, q), b = patch_steps::on_side(gs, gq);
          EXPECT_LT((moved.patches[pieces[h2].first].eval(a.x(), a.y()) - moved.patches[g].eval(b.x(), b.y())).norm(), 1e-9);
        }
    // The layout given back keeps its T-junctions and its faces' halvings.
    const PatchLayout back = layout_from_json(layout_to_json(one.layout), "layout.json");
    EXPECT_EQ(back.levels, one.layout.levels);
    EXPECT_EQ(layout_topology(back, "back").halves.size(), 2u);
  }
  // Graded: a face halved along v once already and cut so again would run at a quarter of its
  // neighbours' speed across its sides 0 and 2, so they are cut along v too (and no further).
  {
    PatchLayout graded = s.layout;
    graded.levels.assign(graded.faces.size(), {0, 0});
    graded.levels[middle] = {0, 1};
    std::vector<int> v_cut(s.patches.size(), 0);
    v_cut[middle] = kCutV;
    v_cut = balance_cuts(graded, T, v_cut);
    EXPECT_EQ(std::count(v_cut.begin(), v_cut.end(), kCutV), 3);
    for (int side : {0, 2}) EXPECT_EQ(v_cut[T.neighbour[middle][side]], kCutV);
  }
  // A cut beside a cube corner (a corner of three patches) is carried to the face across.
  std::vector<int> corner_cuts(s.patches.size(), 0);
  corner_cuts[0] = kCutU;
  corner_cuts = balance_cuts(s.layout, T, corner_cuts);
  EXPECT_GT(std::count_if(corner_cuts.begin(), corner_cuts.end(), [](int k) { return k != 0; }), 1);
  // Cuts elsewhere, one both ways.
  cuts[5] |= kCutU | kCutV;
  cuts = balance_cuts(s.layout, T, cuts);
  const LayoutSplit split = split_layout(s, cuts);
  size_t expect = 0;
  for (int k : cuts) expect += (k & kCutU ? 2 : 1) * (k & kCutV ? 2 : 1);
  ASSERT_EQ(split.layout.faces.size(), expect);
  EXPECT_NO_THROW(layout_topology(split.layout, "split cube"));  // every edge in two faces or a T-junction
  // The seed is the surface as it was: each new patch at (u, v) equals its parent there.
  for (size_t f = 0; f < split.seed.size(); ++f) {
    BezierPatch child;
    child.P = split.seed[f];
    const BezierPatch& parent = s.patches[split.parent[f]];
    const std::string& name = split.layout.names[f];
    const std::string tag = name.substr(name.rfind('/') == std::string::npos ? name.size() : name.rfind('/') + 1);
    double u0 = 0, v0 = 0, du = 1, dv = 1;
    if (tag == "u0" || tag == "u1") du = 0.5, u0 = tag == "u1" ? 0.5 : 0;
    if (tag == "v0" || tag == "v1") dv = 0.5, v0 = tag == "v1" ? 0.5 : 0;
    if (tag.size() == 2 && std::isdigit(static_cast<unsigned char>(tag[0])))
      du = dv = 0.5, u0 = tag[0] == '1' ? 0.5 : 0, v0 = tag[1] == '1' ? 0.5 : 0;
    for (double u : {0.0, 0.3, 1.0})
      for (double v : {0.0, 0.7, 1.0})
        ASSERT_LT((child.eval(u, v) - parent.eval(u0 + du * u, v0 + dv * v)).norm(), 1e-12) << name;
    // Its sides on its parent's same sides: where its piece of the parent's square touches them.
    const std::array<bool, 4> touches = {v0 == 0, u0 + du == 1, v0 + dv == 1, u0 == 0};
    EXPECT_EQ(split.on_parent_side[f], touches) << name;
    // The new corners lie on the surface: each face's corner is its patch's corner.
    for (int k = 0; k < 4; ++k) {
      const double cu = k == 1 || k == 2, cv = k >= 2;
      EXPECT_LT((split.layout.vertices[split.layout.faces[f][k]] - child.eval(cu, cv)).norm(), 1e-9) << name;
    }
  }
  // Refitted from the seed: borders exact, no worse than before.
  const PatchSkin r = fit_patches(split.layout, c.points, c.sides, {}, {}, PatchOptions{}, &split.seed);
  EXPECT_EQ(r.patches.size(), expect);
  EXPECT_LT(r.g0_gap_mm, 1e-9);
  EXPECT_LE(r.side[0].mean, s.side[0].mean * 1.05);
  // A seed of the wrong size is a bug of the caller's.
  std::vector<std::array<Eigen::Vector3d, 16>> wrong(3);
  EXPECT_ANY_THROW(fit_patches(split.layout, c.points, c.sides, {}, {}, PatchOptions{}, &wrong));
}

// A patch that no point falls on (a hole in the scan over a small patch; at 882 patches a
// family hand had one) is held by the penalties and its neighbours. Before, Eigen's product of
// its empty data block divided by zero (SIGFPE).
TEST(Patches, APatchWithoutPointsIsHeldByItsNeighbours) {
  const PatchLayout L = cube_layout(3);
  const Cloud all = ellipsoid_cloud(40000, 0.01);
  Cloud c;  // no point in a cone about +x wider than the middle patch of that face
  for (size_t k = 0; k < all.points.size(); ++k) {
    const Eigen::Vector3d& p = all.points[k];
    if (p.x() > 0 && std::abs(p.y()) < 0.45 * p.x() && std::abs(p.z()) < 0.45 * p.x()) continue;
    c.points.push_back(p), c.sides.push_back(all.sides[k]);
  }
  ASSERT_LT(c.points.size(), all.points.size() - 500);
  const PatchSkin s = fit_patches(L, c.points, c.sides, {}, {}, PatchOptions{});
  ASSERT_EQ(s.patches.size(), 54u);
  for (const auto& q : s.control) ASSERT_TRUE(q.allFinite());
  EXPECT_LT(s.g0_gap_mm, 1e-9);
  // Over the hole (~13 mm across) the fairness and the neighbours keep the surface near the
  // ellipsoid: measured 0.61 mm at most within 10 mm of the hole's middle.
  const Eigen::Vector3d middle = ellipsoid_point(Eigen::Vector3d(1, 0, 0));
  double worst = 0;
  for (const auto& P : s.patches)
    for (int i = 0; i <= 8; ++i)
      for (int j = 0; j <= 8; ++j) {
        const Eigen::Vector3d q = P.eval(i / 8.0, j / 8.0);
        if ((q - middle).norm() < 10) worst = std::max(worst, (q - ellipsoid_point(q)).norm());
      }
  EXPECT_LT(worst, 1.0);
}

// The polygon skin's samples (the support) hold the surface where the scans saw nothing, and
// only there: over a hole in the data the surface follows them; where points were measured
// they are left out (each weighs 1/20 of a point but costs as much in every round). Here the
// support lies 0.5 mm outside the true surface, so where it is used shows.
TEST(Patches, TheSkinSamplesHoldTheSurfaceOnlyWhereNothingWasMeasured) {
  const PatchLayout L = cube_layout(3);
  const Cloud all = ellipsoid_cloud(40000, 0.01);
  Cloud c;  // the hole of APatchWithoutPointsIsHeldByItsNeighbours
  for (size_t k = 0; k < all.points.size(); ++k) {
    const Eigen::Vector3d& p = all.points[k];
    if (p.x() > 0 && std::abs(p.y()) < 0.45 * p.x() && std::abs(p.z()) < 0.45 * p.x()) continue;
    c.points.push_back(p), c.sides.push_back(all.sides[k]);
  }
  std::vector<Eigen::Vector3d> support;
  for (const auto& p : ellipsoid_cloud(20000, 0).points) support.push_back(p + 0.5 * ellipsoid_normal(p));
  const PatchSkin s = fit_patches(L, c.points, c.sides, support, {}, PatchOptions{});
  const Eigen::Vector3d middle = ellipsoid_point(Eigen::Vector3d(1, 0, 0));
  double over_hole = 0, away = 0;
  int n_hole = 0, n_away = 0;
  for (const auto& P : s.patches)
    for (int i = 0; i <= 8; ++i)
      for (int j = 0; j <= 8; ++j) {
        const Eigen::Vector3d q = P.eval(i / 8.0, j / 8.0);
        const double out = (q - ellipsoid_point(q)).dot(ellipsoid_normal(q));
        const double from_middle = (q - middle).norm();
        if (from_middle < 4) over_hole += out, ++n_hole;
        if (from_middle > 25) away += out, ++n_away;
      }
  ASSERT_GT(n_hole, 0);
  ASSERT_GT(n_away, 1000);
  // Over the hole the surface lies out with the support (mean offset measured 0.61 mm; −0.55
  // without a support: it sinks in); where the points were measured it keeps to them (mean
  // offset measured −0.0004 mm; 0.012 with every sample of the support in the fit).
  EXPECT_GT(over_hole / n_hole, 0.3);
  EXPECT_LT(over_hole / n_hole, 0.9);
  EXPECT_LT(std::abs(away / n_away), 0.004);
}

// A refined layout's small patches follow the skin's samples closely. Where the polygon skin's
// guess over an unseen rim leaves the data by millimetres (on the family's H10, a thumb spread
// 55 deg: its web's rim), samples up to 2 mm from the data's last points bent the refit to the
// guess there and it missed those points by ~1 mm, whatever it split; a refit leaves out the
// samples within 5 mm of the data.
TEST(Patches, ARefitTurnsFromTheSkinsGuessWithoutMissingTheDatasEdge) {
  const PatchLayout L = cube_layout(3);
  const Cloud all = ellipsoid_cloud(60000, 0.01);
  Cloud c;  // the cap of the long axis unseen
  for (size_t k = 0; k < all.points.size(); ++k)
    if (all.points[k].x() < 24) c.points.push_back(all.points[k]), c.sides.push_back(all.sides[k]);
  std::vector<Eigen::Vector3d> support;  // the skin's guess: 2.5 mm out
  for (const auto& p : ellipsoid_cloud(20000, 0).points) support.push_back(p + 2.5 * ellipsoid_normal(p));
  const PatchSkin s = fit_patches(L, c.points, c.sides, support, {}, PatchOptions{});
  std::vector<int> cuts(s.patches.size(), kCutU | kCutV);
  const LayoutSplit split = split_layout(s, cuts);
  ASSERT_FALSE(split.layout.levels.empty());
  const PatchSkin r = fit_patches(split.layout, c.points, c.sides, support, {}, PatchOptions{}, &split.seed);
  ASSERT_EQ(r.patches.size(), 4 * s.patches.size());
  // The data's edge (x 22-24 mm) measured on the refit's tessellation, finely.
  const Mesh m = tessellate(r, 16);
  const MeshDistance to_surface(m);
  double edge = 0, elsewhere = 0;
  for (const auto& p : c.points) {
    const double d = to_surface.distance(p);
    (p.x() > 22 ? edge : elsewhere) = std::max(p.x() > 22 ? edge : elsewhere, d);
  }
  // Measured: 0.157 mm at the edge, 0.068 elsewhere (with the samples left out within 2 mm only,
  // as the default fit does: 0.821 and 1.037; the default fit itself 1.04–1.07).
  EXPECT_LT(edge, 0.3);
  EXPECT_LT(elsewhere, 0.15);
}

TEST(Patches, LayoutsAreCheckedOrientedAndSplit) {
  PatchLayout L = cube_layout(1);
  const LayoutTopology T = layout_topology(L, "cube");
  EXPECT_EQ(T.edges, 12u);
  for (int v = 0; v < 8; ++v) {
    EXPECT_EQ(T.valence[v], 3);
    EXPECT_EQ(T.around[v].size(), 3u);
  }
  // One face turned: the topology refuses it, orienting turns it back.
  PatchLayout flipped = L;
  std::reverse(flipped.faces[2].begin(), flipped.faces[2].end());
  EXPECT_NE(test::input_error_of([&] { layout_topology(flipped, "f.json"); }).find("run the same way"), std::string::npos);
  orient_layout(&flipped, "f.json");
  EXPECT_EQ(flipped.faces, L.faces);
  // Open (a face missing): refused, naming the edge.
  PatchLayout open = L;
  open.faces.pop_back();
  EXPECT_NE(test::input_error_of([&] { layout_topology(open, "o.json"); }).find("has one face only"), std::string::npos);
  // Split k × k: k² faces each, the corners kept, the creases split with their edges.
  L.creases = {{0, 1}};
  const PatchLayout S = subdivide_layout(L, 3);
  EXPECT_EQ(S.faces.size(), 54u);
  EXPECT_EQ(S.vertices.size(), 8u + 12 * 2 + 6 * 4);
  EXPECT_EQ(S.creases.size(), 3u);
  EXPECT_NO_THROW(layout_topology(S, "split"));
  // The JSON form round-trips, and a malformed one is one line naming the entry.
  const PatchLayout back = layout_from_json(layout_to_json(S), "l.json");
  EXPECT_EQ(back.faces, S.faces);
  EXPECT_EQ(back.creases, S.creases);
  Json j = layout_to_json(L);
  j["faces"][3] = {0, 1, 2};
  EXPECT_NE(test::input_error_of([&] { layout_from_json(j, "l.json"); }).find("l.json: faces[3] must be 4 vertex indices"),
            std::string::npos);
  j = layout_to_json(L);
  j["faces"][1][2] = 99;
  EXPECT_NE(test::input_error_of([&] { layout_from_json(j, "l.json"); }).find("faces[1] must hold vertex indices in [0, 7]"),
            std::string::npos);
  // Turned inside out (every face's corners the other way): closed and oriented alike, but its
  // patches would face into the hand.
  j = layout_to_json(S);
  for (auto& f : j["faces"]) f = {f[3], f[2], f[1], f[0]};
  EXPECT_NE(test::input_error_of([&] { layout_from_json(j, "l.json"); }).find("l.json: its faces run clockwise seen from outside"),
            std::string::npos);
  // Halvings: graded (neighbours one apart at most) and at most 12; as a refinement leaves
  // them, accepted.
  PatchLayout graded = S;
  graded.levels.assign(S.faces.size(), {0, 0});
  EXPECT_NO_THROW(layout_from_json(layout_to_json(graded), "l.json"));
  graded.levels[4] = {1, 1};
  EXPECT_NO_THROW(layout_from_json(layout_to_json(graded), "l.json"));
  graded.levels[4] = {2, 0};  // two more halvings along u than the faces across its sides 1 and 3
  EXPECT_NE(test::input_error_of([&] { layout_from_json(layout_to_json(graded), "l.json"); })
                .find("l.json: levels[4] halves face 4 2 times across its side 1"),
            std::string::npos);
  for (auto& x : graded.levels) x = {12, 12};
  EXPECT_NO_THROW(layout_from_json(layout_to_json(graded), "l.json"));
  graded.levels[0] = {13, 12};
  EXPECT_NE(test::input_error_of([&] { layout_from_json(layout_to_json(graded), "l.json"); }).find("levels[0] must hold counts in [0, 12]"),
            std::string::npos);
}

// A layout given back lies on its skin when its corners are near the skin's surface, however
// far from its vertices: a refined layout's corner in the middle of the wrist cut's cap, whose
// vertices are its rim (the family's H04: 24-30 mm from the nearest), was refused.
TEST(Patches, ALayoutsCornersAreCheckedAgainstTheSkinsSurface) {
  Mesh cap;  // a 100 mm square of two triangles
  cap.vertices = {{0, 0, 0}, {100, 0, 0}, {100, 100, 0}, {0, 100, 0}};
  cap.faces = {{0, 1, 2}, {0, 2, 3}};
  PatchLayout L = cube_layout(1);
  for (auto& v : L.vertices) v = Eigen::Vector3d(50, 50, 0) + 10 * v.normalized();  // within 20 mm of the square, 40+ mm from its corners
  EXPECT_NO_THROW(check_layout_on_skin(L, cap));
  L.vertices[5].z() += 25;
  EXPECT_NE(test::input_error_of([&] { check_layout_on_skin(L, cap); }).find("corner 5 lies more than 20 mm from the skin"),
            std::string::npos);
}

TEST(Patches, TheLayoutFollowsPatchesCount) {
  PipelineOptions po;
  EXPECT_EQ(patch_options(po).subdivision, 1);  // 96 -> the hand's 98
  po.patches.count = 392;
  EXPECT_EQ(patch_options(po).subdivision, 2);
  po.patches.count = 900;
  EXPECT_EQ(patch_options(po).subdivision, 3);
  EXPECT_NE(test::input_error_of([] {
              parse_pipeline(Json::parse(R"({"format": "handskin-pipeline/1", "patches": {"count": 5}})"), "p");
            }).find("patches.count"),
            std::string::npos);
}

// --patch-tolerance 0.5 on the fixture (issue 38): the patches that miss split, refitted,
// until every measured point lies within 0.5 mm of the surface; at most 300 patches, borders
// exact, the refined net in patches.json (a layout given back fits it again), the refinement
// and its gate in the report.
TEST(Patches, ToleranceSplitsOnlyWhereThePointsMiss) {
  const std::string kBin = HANDSKIN_BINARY, kFix = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";
  const std::string dir = test::temp_dir("patchtol") + "/out";
  std::string out;
  ASSERT_EQ(test::run(kBin + " -q register --back " + kFix + "back --palm " + kFix + "palm --out " + dir, &out), 0) << out;
  const std::string cmd = kBin + " -q patches --skin-dir " + dir + " --rig " + kFix + "rig.json --truth " + kFix + "truth.json";
  ASSERT_EQ(test::run(cmd + " --patch-tolerance 0.5 --out " + dir + "/tol", &out), 0) << out;
  const Json r = load_json_object(dir + "/tol/report.json");
  const Json& f = r["refinement"];
  ASSERT_TRUE(f.is_object());
  EXPECT_EQ(f["tolerance_mm"].get<double>(), 0.5);
  ASSERT_GE(f["fits"].size(), 2u);
  EXPECT_EQ(f["fits"][0]["patches"].get<int>(), 98);  // the thesis's layout first
  EXPECT_GT(f["fits"][0]["over_tolerance"].get<int>(), 0);
  const int n = r["patches"].get<int>();
  EXPECT_GT(n, 98);
  EXPECT_LE(n, 300);
  // Measured (2026-11-30): 98 -> 219 -> 240 -> 277 -> 285 patches, the worst point 0.904 ->
  // 0.676 -> 0.381 -> 0.361 -> 0.362 mm (the later splits for the rough patches, docs/patches.md).
  EXPECT_TRUE(f["held"].get<bool>()) << f.dump();
  for (const char* side : {"palm", "back"}) EXPECT_LE(r["data_to_surface_mm"][side]["max"].get<double>(), 0.5) << side;
  EXPECT_LE(r["continuity"]["g0_gap_mm"].get<double>(), 1e-6);
  // Issue 38's bars on the fixture: data -> surface mean <= 1.2 x the noise floor; against the
  // truth mean <= 0.06, p95 <= 0.2 mm, >= 99.5 % within 1 mm (measured 0.063 / 0.063 against
  // 0.074; 0.055 / 0.160 mm; 100.00 %).
  for (const char* side : {"palm", "back"})
    EXPECT_LE(r["data_to_surface_mm"][side]["mean"].get<double>(), 1.2 * r["table_4_1"]["noise_floor_mm"][side].get<double>());
  EXPECT_LE(r["truth"]["surface_to_truth_mm"]["mean"].get<double>(), 0.06);
  EXPECT_LE(r["continuity"]["g1_normal_jump_deg"]["p95"].get<double>(), 0.3);  // measured 0.106
  // No fold at the webs: a face along a web's bottom is halved across it once at most (before
  // that rule the ring-little web folded by 65-99 deg here). Measured 1.25 deg.
  EXPECT_LE(r["continuity"]["g1_normal_jump_deg"]["max"].get<double>(), 30.0)
      << r["continuity"]["g1_normal_jump_deg"]["max_where"];
  EXPECT_LE(r["truth"]["surface_to_truth_mm"]["p95"].get<double>(), 0.2);
  EXPECT_GE(r["truth"]["truth_to_surface_mm"]["within_1mm"].get<double>(), 0.995);
  bool gate = false, kink = false;
  for (const auto& g : r["gates"]) {
    if (g["name"] == "patches.tolerance") {
      gate = true;
      EXPECT_TRUE(g["pass"].get<bool>());
    }
    // The G1 gate says what the continuity figures measure, and fails when they pass its limit.
    if (g["name"] == "patches.g1_kink") {
      kink = true;
      EXPECT_EQ(g["value"].get<double>(), r["continuity"]["g1_normal_jump_deg"]["max"].get<double>());
      EXPECT_EQ(g["pass"].get<bool>(), g["value"].get<double>() <= g["limit"].get<double>());
    }
  }
  EXPECT_TRUE(gate);
  EXPECT_TRUE(kink);
  // patches.json carries the refined net: its layout has the split faces (names with '/'),
  // and the patches' tessellation is closed.
  const Json p = load_json_object(dir + "/tol/patches.json");
  ASSERT_EQ(p["patches"].size(), static_cast<size_t>(n));
  size_t split = 0;
  for (const auto& patch : p["patches"]) split += patch["name"].get<std::string>().find('/') != std::string::npos;
  EXPECT_GT(split, 0u);
  EXPECT_LT(split, static_cast<size_t>(n));  // not everywhere: only the patches that missed (and their balance)
  const auto m = read_mesh_file(dir + "/tol/patches.ply");
  ASSERT_TRUE(m);
  const MeshHealth h = mesh_health(*m);
  EXPECT_EQ(h.boundary_edges, 0u);
  EXPECT_EQ(h.nonmanifold_vertices, 0u);
  // A tolerance the budget cannot reach: the gate fails and says why; the refinement stops at
  // the budget (patches.max_patches).
  const std::string pipe = test::temp_dir("patchtol") + "/p.json";
  write_file_atomic(pipe, R"({"format": "handskin-pipeline/1", "patches": {"max_patches": 120}})");
  ASSERT_EQ(test::run(cmd + " --patch-tolerance 0.2 --pipeline " + pipe + " --out " + dir + "/tight", &out), 0) << out;
  EXPECT_NE(out.find("patches.tolerance failed"), std::string::npos) << out;
  const Json t = load_json_object(dir + "/tight/report.json");
  EXPECT_LE(t["patches"].get<int>(), 120);
  EXPECT_FALSE(t["refinement"]["held"].get<bool>());
  EXPECT_FALSE(t["refinement"]["stopped"].get<std::string>().empty());
  // Out of range: a usage error naming the flag.
  EXPECT_EQ(test::run(cmd + " --patch-tolerance -1 --out " + dir + "/bad", &out), 2) << out;
  EXPECT_NE(out.find("--patch-tolerance"), std::string::npos) << out;
}

TEST(Patches, TheCommandWritesPatchesOnTheFixture) {
  const std::string kBin = HANDSKIN_BINARY, kFix = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";
  const std::string dir = test::temp_dir("patches") + "/out";
  std::string out;
  ASSERT_EQ(test::run(kBin + " -q register --back " + kFix + "back --palm " + kFix + "palm --out " + dir, &out), 0) << out;
  const std::string cmd = kBin + " -q patches --skin-dir " + dir + " --rig " + kFix + "rig.json --truth " + kFix + "truth.json";
  ASSERT_EQ(test::run(cmd, &out), 0) << out;
  const std::string pdir = dir + "/patches";  // the default --out: its own folder beside the run's files
  EXPECT_FALSE(fs::exists(dir + "/report.json"));  // the run's report would be there: never overwritten
  const Json p = load_json_object(pdir + "/patches.json");
  EXPECT_EQ(p["format"], "handskin-patches/1");
  ASSERT_EQ(p["patches"].size(), 98u);
  EXPECT_EQ(p["layout"]["vertices"].size(), 100u);
  for (const auto& patch : p["patches"]) ASSERT_EQ(patch["control_points"].size(), 16u);
  const std::string obj = read_file(pdir + "/patches.obj");
  size_t surfs = 0;
  for (size_t at = obj.find("\nsurf "); at != std::string::npos; at = obj.find("\nsurf ", at + 1)) ++surfs;
  EXPECT_EQ(surfs, 98u);
  const Json r = load_json_object(pdir + "/report.json");
  EXPECT_LT(r["continuity"]["g0_gap_mm"].get<double>(), 1e-9);
  EXPECT_LT(r["continuity"]["g1_normal_jump_deg"]["median"].get<double>(), 1.0);
  // Away from the corners where other than four patches meet (the issue's bar: 5°); measured
  // 0.44°, and 8.85° while the borders next to those corners were held C1 only where it could.
  EXPECT_LT(r["continuity"]["g1_normal_jump_deg"]["p95"].get<double>(), 5.0);
  for (const char* side : {"palm", "back"}) {
    EXPECT_LT(r["data_to_surface_mm"][side]["mean"].get<double>(), 0.18) << side;  // measured 0.14-0.15 (docs/patches.md)
    // The largest distance is the nearest foot point's: measured 0.85 / 0.93 mm; 2.08 / 1.73
    // when a foot point could stop on a patch's side short of the nearest point across it.
    EXPECT_LT(r["data_to_surface_mm"][side]["max"].get<double>(), 1.3) << side;
    EXPECT_GT(r["data_to_surface_mm"][side]["points"].get<int>(), 50000) << side;
  }
  EXPECT_GT(r["truth"]["truth_to_surface_mm"]["within_1mm"].get<double>(), 0.99);  // measured 99.97 %
  EXPECT_LT(r["truth"]["surface_to_truth_mm"]["mean"].get<double>(), 0.19);          // measured 0.15
  // One closed surface: the tessellation has no open edge, one piece, outward.
  const MeshHealth ph = mesh_health(load_mesh(pdir + "/patches.ply"));
  EXPECT_EQ(ph.boundary_edges, 0u);
  EXPECT_EQ(ph.nonmanifold_vertices, 0u);
  EXPECT_EQ(ph.components, 1u);
  EXPECT_GT(ph.volume_mm3, 0);
  // Same inputs, same bytes.
  const std::string first = read_file(pdir + "/patches.json");
  ASSERT_EQ(test::run(cmd, &out), 0) << out;
  EXPECT_TRUE(first == read_file(pdir + "/patches.json"));
  // The report opens in a browser with nothing else: a headless Chromium draws it (the
  // screenshot is kept with the tests' artefacts).
  const std::string html = read_file(pdir + "/report.html");
  EXPECT_NE(html.find("Table 4.1"), std::string::npos);
  size_t images = 0;
  for (size_t at = html.find("src=\"data:image/png;base64,"); at != std::string::npos;
       at = html.find("src=\"data:image/png;base64,", at + 1))
    ++images;
  EXPECT_EQ(images, 4u);  // the error from the palm and the back, the layout twice
  EXPECT_EQ(html.find("http"), std::string::npos);  // nothing fetched when viewed
  fs::create_directories(HANDSKIN_ARTEFACTS);
  const std::string shot = std::string(HANDSKIN_ARTEFACTS) + "/patches_report.png";
  fs::remove(shot);
  ASSERT_EQ(test::run("command -v chromium", &out), 0) << "chromium is needed for this test (scripts/setup.sh installs it)";
  ASSERT_EQ(test::run("chromium --headless --no-sandbox --disable-gpu --hide-scrollbars --window-size=1400,2400 "
                      "--screenshot=" + shot + " file://" + pdir + "/report.html",
                      &out),
            0)
      << out;
  ASSERT_TRUE(fs::exists(shot)) << out;
  EXPECT_GT(fs::file_size(shot), 100000u);  // pictures and tables, not a blank page
  // Without a rig to find, a clear error.
  EXPECT_EQ(test::run(kBin + " -q patches --skin-dir " + dir + " --out " + dir + "/x", &out), 2);
  EXPECT_NE(out.find("give --rig"), std::string::npos) << out;
}

// On a run folder, `patches` fits the folder's own skin (skin.ply with skin_grid.json): the
// run's patches again, byte for byte, without building the skin. A malformed skin_grid.json
// is one line naming it and the key; a folder whose skin was built on another rig gets its
// skin built again on the rig given, and says so.
TEST(Patches, TheCommandFitsTheRunFoldersOwnSkin) {
  const std::string kBin = HANDSKIN_BINARY, kFix = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";
  const std::string dir = test::temp_dir("patches-folder-skin") + "/run";
  fs::copy(test::default_fixture_run(), dir, fs::copy_options::recursive);
  ASSERT_TRUE(fs::exists(dir + "/skin_grid.json"));
  std::string out;
  ASSERT_EQ(test::run(kBin + " patches --skin-dir " + dir + " --out " + dir + "/p", &out), 0) << out;
  EXPECT_NE(out.find("skin_grid.json"), std::string::npos) << out;
  EXPECT_EQ(out.find("building the skin"), std::string::npos) << out;
  EXPECT_TRUE(read_file(dir + "/p/patches.json") == read_file(dir + "/patches.json"));
  // Another rig (a fingertip 0.5 mm away): the skin is built again on it.
  Rig moved = load_rig(kFix + "rig.json");
  moved.joints[joint_index("index-finger-tip").value()] += Eigen::Vector3d(0.5, 0, 0);
  save_rig(dir + "/moved_rig.json", moved);
  ASSERT_EQ(test::run(kBin + " patches --skin-dir " + dir + " --rig " + dir + "/moved_rig.json --out " + dir + "/q", &out), 0)
      << out;
  EXPECT_NE(out.find("built on another rig"), std::string::npos) << out;
  EXPECT_NE(out.find("building the skin"), std::string::npos) << out;
  // Malformed: refused in one line, nothing written.
  Json grid = load_json_object(dir + "/skin_grid.json");
  grid["tubes"].erase(5);
  save_json(dir + "/skin_grid.json", grid);
  EXPECT_EQ(test::run(kBin + " -q patches --skin-dir " + dir + " --out " + dir + "/r", &out), 1);
  EXPECT_NE(out.find("skin_grid.json: 'tubes' must hold 6 tubes"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir + "/r"));
  grid = load_json_object(dir + "/skin_grid.json");
  grid["format"] = "handskin-skin-grid/9";
  save_json(dir + "/skin_grid.json", grid);
  EXPECT_EQ(test::run(kBin + " -q patches --skin-dir " + dir + " --out " + dir + "/r", &out), 1);
  EXPECT_NE(out.find("skin_grid.json: key 'format' must be \"handskin-skin-grid/1\""), std::string::npos) << out;
}

TEST(Patches, FollowThePostureAndTheirLayoutComesBack) {
  const std::string kBin = HANDSKIN_BINARY, kFix = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";
  const std::string dir = test::temp_dir("patches-layout") + "/out";
  std::string out;
  ASSERT_EQ(test::run(kBin + " -q register --back " + kFix + "back --palm " + kFix + "palm --out " + dir, &out), 0) << out;
  const std::string base = kBin + " -q patches --skin-dir " + dir + " --rig " + kFix + "rig.json";
  ASSERT_EQ(test::run(base, &out), 0) << out;
  // The layout given back reproduces the patches byte for byte.
  ASSERT_EQ(test::run(base + " --layout " + dir + "/patches/patches.json --out " + dir + "/again", &out), 0) << out;
  EXPECT_TRUE(read_file(dir + "/patches/patches.json") == read_file(dir + "/again/patches.json"));
  // A layout of its own (here the same corners and faces, as a handskin-patch-layout/1 file).
  Json layout = {{"format", "handskin-patch-layout/1"}, {"layout", load_json_object(dir + "/patches/patches.json")["layout"]}};
  save_json(dir + "/layout.json", layout);
  ASSERT_EQ(test::run(base + " --layout " + dir + "/layout.json --out " + dir + "/mine", &out), 0) << out;
  const Json mine = load_json_object(dir + "/mine/patches.json");
  EXPECT_EQ(mine["patches"].size(), 98u);
  for (const auto& p : mine["patches"]) ASSERT_EQ(p["control_point_links"].size(), 16u);
  // Bad layouts: one line naming the file and the entry, nothing written.
  Json open = layout;
  open["layout"]["faces"].erase(open["layout"]["faces"].size() - 1);
  open["layout"]["names"].erase(open["layout"]["names"].size() - 1);
  save_json(dir + "/bad.json", open);
  EXPECT_EQ(test::run(base + " --layout " + dir + "/bad.json --out " + dir + "/bad", &out), 1);
  EXPECT_NE(out.find("bad.json: layout: edge"), std::string::npos) << out;
  EXPECT_NE(out.find("has one face only"), std::string::npos) << out;
  test::write_text(dir + "/bad2.json", R"({"format": "handskin-patch-layout/1", "tubes": []})");
  EXPECT_EQ(test::run(base + " --layout " + dir + "/bad2.json --out " + dir + "/bad", &out), 1);
  EXPECT_NE(out.find("bad2.json: missing key 'layout'"), std::string::npos) << out;
  Json far = layout;
  far["layout"]["vertices"][5] = {500, 0, 0};
  save_json(dir + "/bad3.json", far);
  EXPECT_EQ(test::run(base + " --layout " + dir + "/bad3.json --out " + dir + "/bad", &out), 1);
  EXPECT_NE(out.find("corner 5 lies more than 20 mm from the skin"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir + "/bad"));

  // A posture moves the patches with their links; shared borders stay shared.
  const Rig rig = load_palm_rig(kFix + "rig.json");
  const MergedArrays m = read_merged(dir + "/merged.ply");
  const SkinResult skin = build_skin(m.points, rig, skin_options(PipelineOptions{}));
  const PatchSkin s = fit_patch_skin(skin, rig, m.points, m.sides, patch_options(PipelineOptions{}));
  // The fixture's patches lie near its polygon skin (5 x 5 samples per patch: p95 0.37 mm), so
  // the layout is fitted once. Another layout moves the palm ring the thumb's base ends at:
  // still closed and of 98 faces, the thumb's first row grown from another ring, the rest of
  // the palm's rim where it was.
  ASSERT_EQ(s.layout_tries.size(), 1u);
  EXPECT_EQ(s.thumb_ring_shift, 0);
  EXPECT_LT(s.layout_tries[0].second, 0.75);
  // fit_patch_skin measures only the fit it keeps: what it returns is measured, and a fit
  // measured later (patch_steps::measure_pending) has the same distances as one measured at once.
  EXPECT_FALSE(s.pending_measure);
  ASSERT_EQ(s.samples.size(), m.points.size());  // the fixture's points all lie near its skin: each is measured
  {
    const PatchLayout L0 = subdivide_layout(hand_patch_layout(skin, rig, m.points, m.sides), 1);
    const std::vector<Eigen::Vector3d> support = sample_surface(skin.mesh, 0.5);
    const PatchOptions o = patch_options(PipelineOptions{});
    PatchSkin later = patch_steps::fit_patches_unmeasured(L0, m.points, m.sides, support, skin.bones, o);
    ASSERT_TRUE(later.pending_measure);
    EXPECT_TRUE(later.samples.empty());
    patch_steps::measure_pending(&later, m.points, m.sides);
    EXPECT_FALSE(later.pending_measure);
    ASSERT_EQ(later.samples.size(), s.samples.size());
    for (size_t k = 0; k < s.samples.size(); k += 97) {
      EXPECT_EQ(later.samples[k].error, s.samples[k].error) << k;
      EXPECT_EQ(later.samples[k].patch, s.samples[k].patch) << k;
    }
    EXPECT_EQ(later.side[0].mean, s.side[0].mean);
    EXPECT_EQ(later.side[1].max, s.side[1].max);
    EXPECT_EQ(later.worst_patch, s.worst_patch);
  }
  {
    const PatchLayout L0 = hand_patch_layout(skin, rig, m.points, m.sides);
    auto corner = [](const PatchLayout& L, const std::string& face, int k) {
      const auto it = std::find(L.names.begin(), L.names.end(), face);
      return L.vertices[L.faces[it - L.names.begin()][k]];
    };
    for (int shift : {-2, 2}) {
      const PatchLayout L = hand_patch_layout(skin, rig, m.points, m.sides, shift);
      EXPECT_NO_THROW(layout_topology(L, "shifted"));
      ASSERT_EQ(L.faces.size(), 98u);
      double thumb_moved = 0, wrist_moved = 0;
      for (int k = 0; k < 4; ++k) {
        thumb_moved = std::max(thumb_moved, (corner(L, "palm.2.radial", k) - corner(L0, "palm.2.radial", k)).norm());
        wrist_moved = std::max(wrist_moved, (corner(L, "wrist.0", k) - corner(L0, "wrist.0", k)).norm());
      }
      EXPECT_GT(thumb_moved, 3.0) << shift;  // two of the skin's rings: ~7 mm
      EXPECT_LT(wrist_moved, 1e-9) << shift;
    }
    // The thumb's base turned round the palm (a thumb grown from the palm's side): its corners
    // on rings 1 and 2 — on the palm (p0, two of palm.1.palm0's corners) and on the back (b0,
    // two of thumb.0.back's) — go toward the palm for a positive turn and toward the back for a
    // negative one; the wrist's and the fingers' corners stay.
    Eigen::Vector3d back_mean = Eigen::Vector3d::Zero(), palm_mean = Eigen::Vector3d::Zero();
    double nb = 0, np = 0;
    for (size_t k = 0; k < m.points.size(); ++k)
      (m.sides[k] == 1 ? back_mean : palm_mean) += m.points[k], ++(m.sides[k] == 1 ? nb : np);
    const Eigen::Vector3d dorsal = (back_mean / nb - palm_mean / np).normalized();
    for (double turn : {20.0, -20.0}) {
      const PatchLayout L = hand_patch_layout(skin, rig, m.points, m.sides, 0, turn);
      EXPECT_NO_THROW(layout_topology(L, "turned"));
      ASSERT_EQ(L.faces.size(), 98u);
      for (const char* face : {"palm.1.palm0", "thumb.0.back"}) {
        double toward_back = 0;  // the face's corners' moves along the dorsal axis, summed
        for (int k = 0; k < 4; ++k) toward_back += (corner(L, face, k) - corner(L0, face, k)).dot(dorsal);
        EXPECT_GT(turn > 0 ? -toward_back : toward_back, 1.0) << turn << " " << face;
      }
      double still = 0;
      for (const char* face : {"wrist.0", "wrist.3", "index.0.palm", "middle.0.back"})
        for (int k = 0; k < 4; ++k) still = std::max(still, (corner(L, face, k) - corner(L0, face, k)).norm());
      EXPECT_LT(still, 1e-9) << turn;
    }
  }
  // The layout pictures colour neighbouring patches differently (skin tone, blue, green…):
  // both warm and cool patches cover much of the hand. (A release build once drew every patch
  // in the first colour: the colour's index, std::min of it and a literal, read as garbage.)
  {
    const PatchReportPictures pics = patch_report_pictures(s, rig);
    for (const std::string* png : {&pics.layout_back, &pics.layout_palm}) {
      const Rgb8Image img = decode_rgb8_png(*png, "layout picture");
      size_t warm = 0, cool = 0, hand = 0;
      for (size_t k = 0; k + 2 < img.rgb.size(); k += 3) {
        const int r = img.rgb[k], b = img.rgb[k + 2];
        if (r > 235 && b > 235) continue;  // the background
        ++hand;
        warm += r > b + 25, cool += b > r + 25;
      }
      EXPECT_GT(warm, hand / 5) << warm << " of " << hand;
      EXPECT_GT(cool, hand / 5) << cool << " of " << hand;
    }
  }
  // Every point's reported distance is its nearest foot point's: never more than its distance
  // to the nearest of 41 × 41 samples of every patch (an upper bound of the true distance).
  // Newton alone stopped short on folds, on ridges between two patches and on a groove's far
  // sheet: 50 of the fixture's points were reported up to 1.79 mm farther than such a sample.
  {
    std::vector<Eigen::Vector3d> dense;
    for (const auto& P : s.patches)
      for (int i = 0; i <= 40; ++i)
        for (int j = 0; j <= 40; ++j) dense.push_back(P.eval(i / 40.0, j / 40.0));
    const PointGrid grid(dense, 1.0);
    size_t over = 0;
    double worst = 0;
    for (const auto& q : s.samples) {
      const int k = grid.nearest(q.p, q.error + 1e-3);
      if (k < 0) continue;  // no sample nearer than the reported distance
      const double excess = q.error - (dense[k] - q.p).norm();
      if (excess > 1e-3) ++over, worst = std::max(worst, excess);
    }
    EXPECT_EQ(over, 0u) << "worst excess " << worst << " mm";
  }
  const Skeleton skel(rig);
  Angles zero{};
  const PatchSkin same = pose_patch_skin(s, skel, zero);
  for (size_t p = 0; p < s.patches.size(); ++p)
    for (int k = 0; k < 16; ++k) EXPECT_LT((same.patches[p].P[k] - s.patches[p].P[k]).norm(), 1e-9);
  Angles bent{};
  bent[dof_index("index.pip.flex").value()] = 60;
  const PatchSkin posed = pose_patch_skin(s, skel, bent);
  double index_tip = 0, palm_most = 0;
  for (size_t p = 0; p < s.patches.size(); ++p)
    for (int k = 0; k < 16; ++k) {
      const std::string& b = s.bones[s.patches[p].cp_link[k]];
      const double d = (posed.patches[p].P[k] - s.patches[p].P[k]).norm();
      // The links that start at the index PIP (I3) and DIP (I4) move; no other.
      if (b.rfind("index-finger-phalanx-intermediate>", 0) == 0 || b.rfind("index-finger-phalanx-distal>", 0) == 0)
        index_tip = std::max(index_tip, d);
      else
        palm_most = std::max(palm_most, d);
    }
  EXPECT_GT(index_tip, 10.0);      // a 60° bend swings the distal phalanges by centimetres
  EXPECT_LT(palm_most, 1e-9);      // nothing else moves
  const Mesh a = tessellate(s, 4), b = tessellate(posed, 4);
  EXPECT_EQ(mesh_health(a).boundary_edges, mesh_health(b).boundary_edges);  // no crack opened

  // Bound smoothly from the skin's bone-heat weights (as run and the patches command do): the
  // control points near the bent joint blend their links' motions, and the posed patches lie
  // on the polygon skin posed with the same weights, closed still.
  BindingOptions bo;
  const SkinBinding sb = bind_skin(skin.mesh, bones_from_rig(rig), bo);
  PatchSkin smooth = s;
  bind_patch_controls(&smooth, skin.mesh, sb);
  ASSERT_EQ(smooth.control_weights.size(), smooth.control.size());
  for (const VertexWeights& w : smooth.control_weights) {
    double sum = 0;
    for (int k = 0; k < kMaxInfluences; ++k)
      if (w.link[k] >= 0) sum += w.weight[k];
    ASSERT_NEAR(sum, 1.0, 1e-5);
  }
  const PatchSkin smooth_rest = pose_patch_skin(smooth, skel, zero);
  for (size_t k = 0; k < s.control.size(); ++k) ASSERT_LT((smooth_rest.control[k] - s.control[k]).norm(), 1e-9);
  const PatchSkin smooth_bent = pose_patch_skin(smooth, skel, bent);
  size_t blended = 0;  // moved, by other than their rigid link's motion
  for (size_t k = 0; k < s.control.size(); ++k) {
    const double d_smooth = (smooth_bent.control[k] - s.control[k]).norm();
    const double d_rigid = (posed.control[k] - s.control[k]).norm();
    if (d_smooth > 0.5 && std::abs(d_smooth - d_rigid) > 0.5) ++blended;
  }
  EXPECT_GT(blended, 5u);
  const std::vector<Eigen::Vector3d> skin_bent =
      deform(skin.mesh.vertices, sb, link_motions(skel, bent), Blend::DualQuaternion);
  const MeshDistance to_skin(Mesh{skin_bent, skin.mesh.faces});
  std::vector<Eigen::Vector3d> tv;
  tessellation_vertices(smooth_bent, 8, &tv);
  std::vector<double> d;
  for (const auto& v : tv) d.push_back(to_skin.distance(v));
  std::sort(d.begin(), d.end());
  double mean = 0;
  for (double x : d) mean += x / d.size();
  // At rest the patches lie 0.14 mm from the skin on average, p95 0.38 mm (the report's
  // surface_to_skin_mm); posed, the same weights keep them near it: measured 0.166 / 0.477 mm
  // (the rigid binding's patches: 0.227 / 0.868, max 4.0 mm, where the PIP bends).
  EXPECT_LT(mean, 0.2);
  EXPECT_LT(d[d.size() * 95 / 100], 0.6);
  EXPECT_EQ(mesh_health(tessellate(smooth_bent, 4)).boundary_edges, mesh_health(a).boundary_edges);
  // The command writes the weights, named by link, per control point id.
  const Json written = load_json_object(dir + "/patches/patches.json");
  ASSERT_TRUE(written.contains("control_point_weights"));
  EXPECT_EQ(written["control_point_weights"].size(), s.control.size());
  EXPECT_NE(written["binding"].get<std::string>().find("smooth"), std::string::npos);
}

TEST(Patches, TessellationVerticesAreTheMeshVertices) {
  // The tessellation's vertices (each corner and shared border made once) against the patches
  // evaluated independently at every sample's parameters.
  const Cloud c = ellipsoid_cloud(8000, 0.0);
  const PatchSkin s = fit_patches(cube_layout(2), c.points, c.sides, {}, {}, PatchOptions{});
  for (int n : {1, 5, 16}) {
    const Mesh m = tessellate(s, n);
    std::vector<Eigen::Vector3d> v;
    tessellation_vertices(s, n, &v);
    ASSERT_EQ(v.size(), m.n_vertices());
    // corners + (n − 1) per layout edge + (n − 1)² per face
    EXPECT_EQ(v.size(), s.layout.vertices.size() + (n - 1) * 2 * s.patches.size() + (n - 1) * (n - 1) * s.patches.size());
    const PointGrid grid(v, 1.0);
    for (const auto& p : s.patches)
      for (int i = 0; i <= n; ++i)
        for (int j = 0; j <= n; ++j) {
          const Eigen::Vector3d q = p.eval(static_cast<double>(i) / n, static_cast<double>(j) / n);
          const int k = grid.nearest(q, 1.0);
          ASSERT_GE(k, 0);
          ASSERT_LT((v[k] - q).norm(), 1e-9);
        }
    for (size_t k = 0; k < m.n_vertices(); ++k) ASSERT_LT((v[k] - m.vertices[k]).norm(), 1e-12);
  }
}

TEST(Patches, ASurfacePassingThroughItselfIsFoundAndNamed) {
  const Cloud c = ellipsoid_cloud(8000, 0.0);
  PatchSkin s = fit_patches(cube_layout(2), c.points, c.sides, {}, {}, PatchOptions{});
  std::vector<int> face_patch;
  const Mesh m = tessellate(s, 8, &face_patch);
  ASSERT_EQ(face_patch.size(), m.n_faces());
  for (size_t f = 0; f < face_patch.size(); ++f) ASSERT_EQ(face_patch[f], static_cast<int>(f / 128)) << f;  // 8 x 8 quads a patch
  const PatchCrossings none = tessellation_crossings(s, m, face_patch);
  EXPECT_EQ(none.pairs, 0u);
  EXPECT_TRUE(none.patches.empty());
  // The top patch whose middle lies highest: its four inner control points pushed down through
  // the body, below its bottom (the ellipsoid's half-height is 15 mm), its borders left shared.
  size_t top = 0;
  for (size_t f = 0; f < s.patches.size(); ++f)
    if (s.patches[f].eval(0.5, 0.5).z() > s.patches[top].eval(0.5, 0.5).z()) top = f;
  for (int k : {5, 6, 9, 10}) s.patches[top].P[k].z() = -40.0;
  std::vector<int> fp;
  const Mesh crossed = tessellate(s, 8, &fp);
  const PatchCrossings found = tessellation_crossings(s, crossed, fp);
  EXPECT_GT(found.pairs, 0u);
  ASSERT_FALSE(found.patches.empty());
  for (const auto& w : found.patches) EXPECT_NE(w.find(s.patches[top].name), std::string::npos) << w;
  // A pair of patches is named once, as "a | b" with a < b.
  for (const auto& w : found.patches) {
    if (const size_t bar = w.find(" | "); bar != std::string::npos) {
      EXPECT_LT(w.substr(0, bar), w.substr(bar + 3)) << w;
    }
  }
  EXPECT_TRUE(std::is_sorted(found.patches.begin(), found.patches.end()));
}

// The first two faces of a layout that share a side, and that side's two corners ({-1, -1, ..} when none do).
std::tuple<int, int, std::array<int, 2>> two_faces_sharing_a_side(const PatchLayout& L) {
  const auto& F = L.faces;
  for (size_t a = 0; a < F.size(); ++a)
    for (size_t b = a + 1; b < F.size(); ++b)
      for (int k = 0; k < 4; ++k)
        for (int m = 0; m < 4; ++m)
          if (F[a][k] == F[b][(m + 1) % 4] && F[a][(k + 1) % 4] == F[b][m])
            return {static_cast<int>(a), static_cast<int>(b), std::array<int, 2>{F[a][k], F[a][(k + 1) % 4]}};
  return {-1, -1, std::array<int, 2>{-1, -1}};
}

// Two faces held apart (Separation, as fit_patch_skin holds two fingers' tubes pressed
// together): a plane through their shared border, turned so that the free fit lies across it;
// fitted again from that surface with the separation, every control point of the first face
// lies on the plane's negative side by the margin, of the second on its positive side, and the
// border's on the plane: the two patches meet along their border only.
TEST(Patches, SeparatedFacesKeepTheirControlPointsEachOnItsSideOfThePlane) {
  const Cloud c = ellipsoid_cloud(8000, 0.0);
  const PatchSkin free = fit_patches(cube_layout(2), c.points, c.sides, {}, {}, PatchOptions{});
  // Two faces sharing a side, and that side's corners.
  const auto [fa, fb, shared] = two_faces_sharing_a_side(free.layout);
  ASSERT_GE(fa, 0);
  const Eigen::Vector3d p0 = free.control[shared[0]], p1 = free.control[shared[1]];
  Eigen::Vector3d ca = Eigen::Vector3d::Zero(), cb = Eigen::Vector3d::Zero();
  for (int k = 0; k < 16; ++k) ca += free.patches[fa].P[k] / 16, cb += free.patches[fb].P[k] / 16;
  const Eigen::Vector3d along = (p1 - p0).normalized();
  Eigen::Vector3d n = (cb - ca) - (cb - ca).dot(along) * along;
  // Turned 50 degrees about the border: part of face a now lies on b's side.
  n = Eigen::AngleAxisd(50 * M_PI / 180, along) * n.normalized();
  Separation sep;
  sep.normal = n;
  sep.offset = n.dot(0.5 * (p0 + p1));
  sep.faces = {std::vector<int>{fa}, std::vector<int>{fb}};
  const auto side_of = [&](const PatchSkin& s, int id) { return n.dot(s.control[id]) - sep.offset; };
  double crossed = -1e9;
  for (int id : free.patch_control[fa]) crossed = std::max(crossed, side_of(free, id));
  for (int id : free.patch_control[fb]) crossed = std::max(crossed, -side_of(free, id));
  ASSERT_GT(crossed, 1.0) << "the free fit must lie across the plane for the test to mean anything";
  std::vector<std::array<Eigen::Vector3d, 16>> seed;
  for (const auto& P : free.patches) seed.push_back(P.P);
  const PatchSkin held = fit_patches(free.layout, c.points, c.sides, {}, {}, PatchOptions{}, &seed, {sep});
  ASSERT_EQ(held.separations.size(), 1u);
  const std::set<int> of_a(held.patch_control[fa].begin(), held.patch_control[fa].end());
  const std::set<int> of_b(held.patch_control[fb].begin(), held.patch_control[fb].end());
  for (int id : of_a) {
    if (of_b.count(id)) {
      EXPECT_NEAR(side_of(held, id), 0.0, 1e-3) << id;
    } else {
      EXPECT_LE(side_of(held, id), -0.9 * kSeparationMarginMm) << id;
    }
  }
  for (int id : of_b) {
    if (!of_a.count(id)) {
      EXPECT_GE(side_of(held, id), 0.9 * kSeparationMarginMm) << id;
    }
  }
  // The rest of the surface still fits the ellipsoid, and the net stays closed.
  EXPECT_LT(held.g0_gap_mm, 1e-9);
  EXPECT_LT(held.side[0].mean + held.side[1].mean, 2 * (free.side[0].mean + free.side[1].mean) + 0.5);
  // A separation without a seed is a bug of the caller's.
  EXPECT_THROW(fit_patches(free.layout, c.points, c.sides, {}, {}, PatchOptions{}, nullptr, {sep}), std::logic_error);
}

// The refinement does not split a face held apart (its control points are bound to its side
// of the plane: the points it misses lie across it, where no split reaches them, and split, the
// bound walls of two pressed fingers folded); the other faces are split as before, and the
// separation follows the faces through the refits.
TEST(Patches, TheRefinementLeavesFacesHeldApartWhole) {
  const Cloud c = ellipsoid_cloud(8000, 0.0);
  const PatchSkin free = fit_patches(cube_layout(2), c.points, c.sides, {}, {}, PatchOptions{});
  const auto [fa, fb, shared] = two_faces_sharing_a_side(free.layout);
  ASSERT_GE(fa, 0);
  Eigen::Vector3d ca = Eigen::Vector3d::Zero(), cb = Eigen::Vector3d::Zero();
  for (int k = 0; k < 16; ++k) ca += free.patches[fa].P[k] / 16, cb += free.patches[fb].P[k] / 16;
  Separation sep;
  sep.normal = (cb - ca).normalized();
  sep.offset = sep.normal.dot(0.5 * (ca + cb));
  sep.faces = {std::vector<int>{fa}, std::vector<int>{fb}};
  std::vector<std::array<Eigen::Vector3d, 16>> seed;
  for (const auto& P : free.patches) seed.push_back(P.P);
  PatchOptions o;
  PatchSkin s = fit_patches(free.layout, c.points, c.sides, {}, {}, o, &seed, {sep});
  // A tolerance every patch misses (the 24 patches' worst points lie farther).
  const std::vector<double> worst = patch_max_error(s);
  o.tolerance_mm = 0.5 * *std::min_element(worst.begin(), worst.end());
  o.refine_rounds = 2;
  const std::string name_a = s.patches[fa].name, name_b = s.patches[fb].name;
  patch_steps::refine_to_tolerance(&s, o, [&](const LayoutSplit& split) {
    return fit_patches(split.layout, c.points, c.sides, {}, {}, o, &split.seed, separations_after_split(s.separations, split));
  });
  ASSERT_TRUE(s.refinement.has_value());
  EXPECT_GT(s.patches.size(), free.patches.size()) << "the other faces are split";
  std::set<std::string> names;
  for (const auto& p : s.patches) names.insert(p.name);
  for (const std::string& n : {name_a, name_b}) {
    EXPECT_TRUE(names.count(n)) << n << " was split";
    for (const auto& m : names) EXPECT_NE(m.rfind(n + "/", 0), 0u) << m;
  }
  ASSERT_EQ(s.separations.size(), 1u);
  ASSERT_EQ(s.separations[0].faces[0].size(), 1u);
  ASSERT_EQ(s.separations[0].faces[1].size(), 1u);
  EXPECT_EQ(s.patches[s.separations[0].faces[0][0]].name, name_a);
  EXPECT_EQ(s.patches[s.separations[0].faces[1][0]].name, name_b);
  EXPECT_FALSE(s.refinement->held);
  EXPECT_LT(s.g0_gap_mm, 1e-6);
}

// A refinement that ends on a surface passing through itself (on the family's H10-s1 the
// thumb's base: 0 → 31 → 144 pairs of triangles over three rounds) is taken back to the round
// that made it cross: the faces whose children cross are left whole and the refinement is made
// again from there. Here the refit of one face's children is made to fold through the
// ellipsoid's far side.
// A split that brings no gain (no patch brought within the tolerance, the worst point no
// nearer) is let go on once: the next split may (on the WebXR hand's left-arched pair, 0.59 ->
// 0.68 mm, then within 0.5 mm), and when it does not either, the fit before them is kept.
TEST(Patches, TheRefinementGoesOnOnceAfterASplitWithoutGain) {
  const Cloud c = ellipsoid_cloud(8000, 0.0);
  PatchOptions o;
  const PatchSkin start = fit_patches(cube_layout(2), c.points, c.sides, {}, {}, o);
  std::vector<double> worst = patch_max_error(start);
  std::sort(worst.begin(), worst.end());
  o.tolerance_mm = 0.5 * (worst[worst.size() - 1] + worst[worst.size() - 2]);  // one patch misses
  o.rough_rounds = 0;
  for (const bool second_gains : {true, false}) {
    int refits = 0;
    const auto refit = [&](const LayoutSplit& split) {
      PatchSkin t = fit_patches(split.layout, c.points, c.sides, {}, {}, o, &split.seed);
      // The first refit (and with !second_gains every one) misses one point by twice the worst.
      if (++refits == 1 || !second_gains) t.samples.front().error = static_cast<float>(2 * worst.back());
      return t;
    };
    PatchSkin s = start;
    patch_steps::refine_to_tolerance(&s, o, refit);
    ASSERT_TRUE(s.refinement.has_value());
    if (second_gains) {
      EXPECT_EQ(refits, 2);
      EXPECT_TRUE(s.refinement->held) << s.refinement->stopped;
      EXPECT_GT(s.patches.size(), start.patches.size());
    } else {
      EXPECT_EQ(refits, 2) << "one split let go on, then stopped";
      EXPECT_FALSE(s.refinement->held);
      EXPECT_EQ(s.patches.size(), start.patches.size()) << "the fit before them kept";
      EXPECT_EQ(s.refinement->patches.size(), 1u);
      EXPECT_NE(s.refinement->stopped.find("which is kept"), std::string::npos) << s.refinement->stopped;
    }
  }
}

TEST(Patches, TheRefinementLeavesWholeTheFacesWhoseSplitMadeTheSurfaceCrossItself) {
  const Cloud c = ellipsoid_cloud(8000, 0.0);
  PatchOptions o;
  PatchSkin s = fit_patches(cube_layout(2), c.points, c.sides, {}, {}, o);
  ASSERT_EQ(crossings(s, o.tessellation).pairs, 0u);
  const std::vector<double> worst = patch_max_error(s);
  o.tolerance_mm = 0.5 * *std::min_element(worst.begin(), worst.end());  // every patch misses
  o.refine_rounds = 1;
  const std::string folded = s.patches[0].name;
  int refits = 0, folds = 0;
  const auto refit = [&](const LayoutSplit& split) {
    ++refits;
    PatchSkin t = fit_patches(split.layout, c.points, c.sides, {}, {}, o, &split.seed);
    for (auto& P : t.patches)
      if (P.name.rfind(folded + "/", 0) == 0) {  // its inner control points through the centre
        ++folds;
        for (int k : {5, 6, 9, 10}) P.P[k] *= -1.5;
      }
    return t;
  };
  PatchSkin plain = s;
  patch_steps::refine_to_tolerance(&plain, o, [&](const LayoutSplit& split) {
    return fit_patches(split.layout, c.points, c.sides, {}, {}, o, &split.seed);
  });
  ASSERT_TRUE(plain.refinement.has_value());
  EXPECT_EQ(plain.refinement->frozen, 0) << "no crossing, nothing left whole";
  patch_steps::refine_to_tolerance(&s, o, refit);
  ASSERT_TRUE(s.refinement.has_value());
  EXPECT_GT(folds, 0) << "the first refit split the face and folded its children";
  EXPECT_EQ(refits, 2) << "the round fitted again";
  EXPECT_GE(s.refinement->frozen, 1);
  std::set<std::string> names;
  for (const auto& p : s.patches) names.insert(p.name);
  EXPECT_TRUE(names.count(folded)) << folded << " was left whole";
  EXPECT_GT(s.patches.size(), 24u) << "the other faces split";
  EXPECT_LT(s.patches.size(), plain.patches.size());
  EXPECT_EQ(crossings(s, o.tessellation).pairs, 0u);
  ASSERT_TRUE(s.crossings.has_value());
  EXPECT_EQ(s.crossings->pairs, 0u) << "the kept fit's own crossings, carried";
  EXPECT_EQ(s.refinement->patches.size(), 2u) << "one entry per fit kept: the layout's and the round's";
  EXPECT_EQ(s.refinement->patches.back(), static_cast<int>(s.patches.size()));
  EXPECT_LT(s.g0_gap_mm, 1e-6);
}

// When every restart of the refinement crosses again, the last fit that did not cross is
// kept, and the report says why the tolerance was not reached.
TEST(Patches, TheRefinementKeepsItsLastUncrossedFitWhenEveryRestartCrosses) {
  const Cloud c = ellipsoid_cloud(8000, 0.0);
  PatchOptions o;
  const PatchSkin start = fit_patches(cube_layout(2), c.points, c.sides, {}, {}, o);
  const std::vector<double> worst = patch_max_error(start);
  o.tolerance_mm = 0.5 * *std::min_element(worst.begin(), worst.end());  // every patch misses
  o.refine_rounds = 1;
  // Every refit folds the children of the first face it finds split, whichever that is: the
  // first refinement and each restart (with the last folded face left whole) cross.
  PatchSkin s = start;
  int refits = 0;
  patch_steps::refine_to_tolerance(&s, o, [&](const LayoutSplit& split) {
    PatchSkin t = fit_patches(split.layout, c.points, c.sides, {}, {}, o, &split.seed);
    ++refits;
    std::string under;
    for (const auto& P : t.patches)
      if (under.empty() && P.name.find('/') != std::string::npos) under = P.name.substr(0, P.name.find('/'));
    for (auto& P : t.patches)
      if (!under.empty() && P.name.rfind(under + "/", 0) == 0)
        for (int k : {5, 6, 9, 10}) P.P[k] *= -1.5;
    return t;
  });
  ASSERT_TRUE(s.refinement.has_value());
  EXPECT_EQ(refits, 3) << "the refinement and two restarts";
  EXPECT_EQ(s.patches.size(), start.patches.size()) << "the fit before the first crossing: the unrefined one";
  EXPECT_EQ(crossings(s, o.tessellation).pairs, 0u);
  EXPECT_NE(s.refinement->stopped.find("taken back"), std::string::npos) << s.refinement->stopped;
  EXPECT_FALSE(s.refinement->held);
  EXPECT_EQ(s.refinement->patches.size(), 1u);
}

TEST(Patches, RandomLayoutsAreRefusedInOneLineOrFitted) {
  // Malformed layouts of every kind (indices out of range, repeated corners, open or
  // non-manifold edges, faces run the same way, creases off the layout): each one is an
  // InputError or a closed, oriented layout whose topology is consistent; never a crash.
  std::mt19937_64 rng(11);
  const PatchLayout cube = cube_layout(1);
  size_t accepted = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    Json j = layout_to_json(cube);
    std::uniform_int_distribution<int> pick(0, 9);
    const int edits = 1 + pick(rng) % 3;
    for (int e = 0; e < edits; ++e) {
      if (j["faces"].empty()) break;
      const int f = static_cast<int>(rng() % j["faces"].size());
      if (!j["faces"][f].is_array() || j["faces"][f].size() != 4) continue;
      switch (pick(rng)) {
        case 0: j["faces"][f][rng() % 4] = static_cast<int>(rng() % 12) - 2; break;
        case 1: j["faces"][f] = {0, 1, 2}; break;
        case 2:
          j["faces"].erase(f);
          if (j["names"].size() > static_cast<size_t>(f)) j["names"].erase(f);
          break;
        case 3: j["faces"].push_back(j["faces"][f]), j["names"].push_back("copy"); break;
        case 4: std::swap(j["faces"][f][0], j["faces"][f][1]); break;
        case 5: j["creases"].push_back({static_cast<int>(rng() % 10) - 1, static_cast<int>(rng() % 10) - 1}); break;
        case 6: j["vertices"][rng() % 8] = {1e308, -1e308, 0}; break;
        case 7: j["faces"][f][0] = 1.5; break;
        case 8: j["names"] = Json::array(); break;
        default: j["faces"][f] = {j["faces"][f][3], j["faces"][f][2], j["faces"][f][1], j["faces"][f][0]}; break;
      }
    }
    try {
      const PatchLayout L = layout_from_json(j, "random.json");
      const LayoutTopology T = layout_topology(L, "random.json");
      for (size_t f = 0; f < L.faces.size(); ++f)
        for (int s = 0; s < 4; ++s) {
          const int g = T.neighbour[f][s], gs = T.neighbour_side[f][s];
          ASSERT_GE(g, 0);
          ASSERT_EQ(T.neighbour[g][gs], static_cast<int>(f));
        }
      ++accepted;
    } catch (const InputError& e) {
      const std::string m = e.what();
      ASSERT_NE(m.find("random.json"), std::string::npos) << m;
      ASSERT_EQ(m.find('\n'), std::string::npos) << m;
    }
  }
  EXPECT_GT(accepted, 0u);  // some edits keep a closed layout (a crease on an edge, a cube turned inside out)
}
