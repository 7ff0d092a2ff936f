// Skin, first steps (issue 5): slicing, nearest-bone segmentation, polar resampling.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/random.hpp"
#include "register/registration.hpp"
#include "skin/auto_rig.hpp"
#include "skin/baseline.hpp"
#include "skin/skin_mesh.hpp"
#include "skin/slices.hpp"
#include "synth/mesh_distance.hpp"
#include "test_util.hpp"
#include "core/atomic_file.hpp"
#include "core/json_util.hpp"

using namespace handskin;
using handskin::test::input_error_of;
using handskin::test::temp_dir;

namespace {
const std::string kFixture = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";

// The fixture pair registered and merged, once per test binary.
const MergedArrays& fixture_merged() {
  static const MergedArrays m = [] {
    const RangeScan back = load_scan(kFixture + "back"), palm = load_scan(kFixture + "palm");
    const Registration reg =
        register_scans(back, palm, "back", "palm", RegistrationOptions{}, nullptr, [](const std::string&) {});
    return merged_arrays(*reg.merged);
  }();
  return m;
}

std::vector<Eigen::Vector3d> fixture_markers() {
  std::vector<Eigen::Vector3d> m;
  const Json t = load_json_object(kFixture + "truth.json");
  for (const auto& p : t["markers_palm"]) m.emplace_back(p[0].get<double>(), p[1].get<double>(), p[2].get<double>());
  return m;
}

void expect_watertight(const SkinResult& s) {
  EXPECT_TRUE(s.health.closed()) << s.health.boundary_edges << " boundary edges";
  EXPECT_TRUE(s.health.manifold()) << s.health.nonmanifold_vertices << " non-manifold vertices";
  EXPECT_EQ(s.health.components, 1u);
  EXPECT_GT(s.health.volume_mm3, 0.0);  // outward
  EXPECT_TRUE(s.self_intersection_checked);
  EXPECT_FALSE(s.self_intersects);
  EXPECT_TRUE(s.watertight());
}

// Points on a cylinder of radius r about the X axis from x0 to x1, noisy, with the band of
// angles [gap_from, gap_to) (deg, about +Y toward +Z) left unmeasured, like a flank.
std::vector<Eigen::Vector3d> cylinder(double r, double x0, double x1, double gap_from, double gap_to, double noise,
                                      Rng* rng) {
  std::vector<Eigen::Vector3d> p;
  for (double x = x0; x <= x1; x += 0.4)
    for (double a = 0; a < 360; a += 2.0) {
      if (a >= gap_from && a < gap_to) continue;
      const double rr = r + rng->normal() * noise, t = a * M_PI / 180;
      p.emplace_back(x, rr * std::cos(t), rr * std::sin(t));
    }
  return p;
}
}  // namespace

TEST(Slices, CylinderResampledRoundItsUnseenFlank) {
  Rng rng(2);
  const auto pts = cylinder(8.0, 0, 100, 160, 215, 0.08, &rng);
  const std::vector<Bone> bones = {{1, 2, {-5, 0, 0}, {105, 0, 0}}};
  SliceOptions o;
  o.planes = 25;
  const Slicing s = slice_cloud(pts, bones, Eigen::Isometry3d::Identity(), o);
  ASSERT_EQ(s.sections.size(), 25u);
  double raw_var = 0, var = 0;
  size_t n = 0;
  for (const auto& sec : s.sections) {
    EXPECT_TRUE(sec.closed);
    EXPECT_NEAR(sec.largest_gap_deg, 57, 3);
    ASSERT_EQ(sec.points.size(), 10u);
    for (size_t i = 0; i < sec.rho.size(); ++i) {
      EXPECT_NEAR(sec.rho[i], 8.0, 0.1) << "plane " << sec.plane << " phi " << sec.phi[i];  // the gap too
      EXPECT_NEAR(std::hypot(sec.points[i].y(), sec.points[i].z()), sec.rho[i], 1e-9);
      raw_var += (sec.rho_raw[i] - 8) * (sec.rho_raw[i] - 8);
      var += (sec.rho[i] - 8) * (sec.rho[i] - 8);
      ++n;
    }
  }
  EXPECT_LT(var, raw_var);  // smoothing across planes takes noise (wrinkles) out
}

TEST(Slices, TwoLinksInASlabSplitIntoDorsalAndPalmarArcs) {
  // A flat slab 40 mm wide, 12 mm thick around two parallel links: each link's sector is a
  // top and a bottom arc with the other link's sector between.
  std::vector<Eigen::Vector3d> pts;
  for (double x = 0; x <= 60; x += 0.5)
    for (double y = -20; y <= 20; y += 0.4) pts.emplace_back(x, y, 6), pts.emplace_back(x, y, -6);
  const std::vector<Bone> bones = {{1, 2, {-1, -10, 0}, {61, -10, 0}}, {3, 4, {-1, 10, 0}, {61, 10, 0}}};
  SliceOptions o;
  o.planes = 10;
  const Slicing s = slice_cloud(pts, bones, Eigen::Isometry3d::Identity(), o);
  ASSERT_EQ(s.sections.size(), 20u);
  for (const auto& sec : s.sections) {
    EXPECT_FALSE(sec.closed);
    EXPECT_EQ(sec.arcs, 2);
    for (const auto& p : sec.points) EXPECT_NEAR(std::abs(p.z()), 6.0, 0.15);  // on the faces, never across
  }
}

TEST(Slices, FixtureEveryLinkSlicedNearTheTrueSkin) {
  const Slicing s = slice_cloud(fixture_merged().points, load_rig(kFixture + "rig.json"), SliceOptions{});
  EXPECT_EQ(s.plane_x.size(), 50u);
  std::vector<int> per_bone(s.bones.size(), 0);
  for (const auto& sec : s.sections) ++per_bone[sec.bone];
  for (size_t b = 0; b < s.bones.size(); ++b) EXPECT_GE(per_bone[b], 4) << s.bones[b].name();
  const MeshDistance truth(load_mesh(kFixture + "truth_skin.ply"));
  std::vector<double> d;
  for (const auto& sec : s.sections)
    for (const auto& p : sec.points) d.push_back(truth.distance(p));
  std::sort(d.begin(), d.end());
  // Figures of this first cut (docs/skin.md); the finished stage must reach the issue's.
  EXPECT_LT(d[d.size() / 2], 0.12);
  EXPECT_LT(d[d.size() * 9 / 10], 0.5);
}

TEST(SkinBaseline, CgalPoissonOnTheFixtureIsClosedAndItsErrorIsMeasured) {
  // The reconstruction a user would otherwise run on the merged cloud; its figures are what
  // the strip skin must beat (docs/skin.md).
  const MergedArrays& m = fixture_merged();
  const BaselineResult b = poisson_baseline(m.points, m.normals);
  const MeshHealth h = mesh_health(b.mesh);
  EXPECT_TRUE(h.closed());
  EXPECT_TRUE(h.manifold());
  EXPECT_EQ(h.components, 1u);
  EXPECT_GT(h.volume_mm3, 0.0);
  const TriMesh truth = load_mesh(kFixture + "truth_skin.ply");
  const MeshDistance to_baseline(b.mesh);
  size_t within = 0;
  for (const Eigen::Vector3d& p : mesh_vertices(truth)) within += to_baseline.distance(p) <= 1.0;
  const double share = static_cast<double>(within) / static_cast<double>(truth.n_vertices());
  EXPECT_GT(share, 0.9);  // measured 0.973
}

TEST(SkinMesh, FixtureSkinIsWatertightLabelledAndMeetsTheIssueFigures) {
  const MergedArrays& m = fixture_merged();
  const SkinResult s = build_skin(m.points, load_rig(kFixture + "rig.json"), SkinOptions{});
  expect_watertight(s);
  EXPECT_GE(s.health.faces, 6000u);
  EXPECT_LE(s.health.faces, 10000u);
  EXPECT_TRUE(s.warnings.empty()) << s.warnings.front();
  ASSERT_EQ(s.vertex_bone.size(), s.health.vertices);
  std::vector<int> per_tube(kSkinTubes, 0);
  for (size_t i = 0; i < s.vertex_bone.size(); ++i) {
    ASSERT_GE(s.vertex_bone[i], 0);
    ASSERT_LT(s.vertex_bone[i], 24);
    ASSERT_GE(s.vertex_tube[i], 0);
    ASSERT_LT(s.vertex_tube[i], kSkinTubes);
    ++per_tube[s.vertex_tube[i]];
  }
  for (int t = 0; t < kSkinTubes; ++t) EXPECT_GT(per_tube[t], 200) << skin_tube_name(t);
  // Against the true skin, away from the markers (whose skin no scan saw).
  const TriMesh truth = load_mesh(kFixture + "truth_skin.ply");
  const MeshDistance to_truth(truth), to_skin(s.mesh);
  const auto markers = fixture_markers();
  const OneWayDistance a = one_way_distance(sample_surface(s.mesh, 2.0), to_truth, markers, 7.0);
  const OneWayDistance b = one_way_distance(sample_surface(truth, 2.0), to_skin, markers, 7.0);
  EXPECT_LE(a.mean, 0.15);   // measured 0.10
  EXPECT_LE(a.p95, 0.5);     // measured 0.34
  EXPECT_GE(b.within_1mm, 0.98);  // measured 0.993
}

TEST(SkinMesh, AutomaticSkeletonWithin3mmOfTheTrueRig) {
  const MergedArrays& m = fixture_merged();
  const AutoRig a = place_skeleton(m.points, m.sides);
  const JointError e = joint_error(a.rig, load_rig(kFixture + "rig.json"));
  EXPECT_LE(e.mean_mm, 3.0) << "worst " << e.worst_joint << " " << e.max_mm;  // measured 1.8
  EXPECT_LE(e.max_mm, 8.0);
  EXPECT_NEAR(a.scale, 1.0, 0.05);  // the fixture hand is the nominal one
  EXPECT_EQ(a.side, HandSide::Right);
  // Mirrored: a left hand, placed as one (its joints the mirrored rig's), not mislabelled.
  std::vector<Eigen::Vector3d> mirrored = m.points;
  for (auto& p : mirrored) p.y() = -p.y();
  Rig mirrored_rig = load_rig(kFixture + "rig.json");
  for (auto& j : mirrored_rig.joints) j.y() = -j.y();
  mirrored_rig.palm_normal->y() = -mirrored_rig.palm_normal->y();
  const AutoRig l = place_skeleton(mirrored, m.sides);
  EXPECT_EQ(l.side, HandSide::Left);
  EXPECT_EQ(rig_side(l.rig), HandSide::Left);
  const JointError el = joint_error(l.rig, mirrored_rig);
  EXPECT_NEAR(el.mean_mm, e.mean_mm, 0.05) << "worst " << el.worst_joint;
}

TEST(SkinMesh, MissingFingerIsAWarningAndTheRestStaysWatertight) {
  const MergedArrays& m = fixture_merged();
  const Rig rig = load_rig(kFixture + "rig.json");
  const auto bones = bones_from_rig(rig);
  std::vector<Eigen::Vector3d> kept;
  for (const auto& p : m.points) {
    size_t best = 0;
    double bd = 1e300;
    for (size_t b = 0; b < bones.size(); ++b) {
      const Eigen::Vector3d ab = bones[b].b - bones[b].a;
      const double t = std::clamp((p - bones[b].a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
      const double d = (bones[b].a + t * ab - p).squaredNorm();
      if (d < bd) bd = d, best = b;
    }
    const std::string n = bones[best].name();
    if (n.rfind("pinky-finger-phalanx", 0) == 0) continue;  // the little finger's phalanges
    kept.push_back(p);
  }
  const SkinResult s = build_skin(kept, rig, SkinOptions{});
  expect_watertight(s);
  ASSERT_FALSE(s.warnings.empty());
  EXPECT_NE(s.warnings.front().find("little"), std::string::npos) << s.warnings.front();
  EXPECT_FALSE(s.tubes[static_cast<int>(SkinTube::Little)].present);
}

TEST(SkinMesh, HoleAcrossTheHandIsFilledFromNeighbouringRings) {
  const MergedArrays& m = fixture_merged();
  const Rig rig = load_rig(kFixture + "rig.json");
  const Eigen::Isometry3d T = hand_frame_from_rig(rig);
  std::vector<Eigen::Vector3d> kept;
  for (const auto& p : m.points) {
    const double x = (T * p).x();
    if (x > 30 && x < 42) continue;  // a 12 mm band of the palm unscanned
    kept.push_back(p);
  }
  const SkinResult s = build_skin(kept, rig, SkinOptions{});
  expect_watertight(s);
  EXPECT_GE(s.tubes[0].filled, 2);
  const MeshDistance to_truth(load_mesh(kFixture + "truth_skin.ply"));
  const OneWayDistance a = one_way_distance(sample_surface(s.mesh, 1.0), to_truth, fixture_markers(), 7.0);
  EXPECT_LT(a.p95, 1.0);
}

TEST(SkinMesh, RigFromAnotherScanIsAClearError) {
  const MergedArrays& m = fixture_merged();
  Rig rig = load_rig(kFixture + "rig.json");
  for (auto& j : rig.joints) j += Eigen::Vector3d(400, 0, 0);
  const std::string e = input_error_of([&] { build_skin(m.points, rig, SkinOptions{}); });
  EXPECT_NE(e.find("outside the merged cloud"), std::string::npos) << e;
  SkinOptions bad;
  bad.max_triangles = 10;
  EXPECT_NE(input_error_of([&] { build_skin(m.points, load_rig(kFixture + "rig.json"), bad); }).find("max_triangles"),
            std::string::npos);
}

TEST(SkinMesh, RigShiftedSidewaysIsRefusedAndTheErrorNamesTheDigit) {
  // A rig shifted sideways does not fit: some digit's links lie beside the middle of its
  // sections. Refused (not worked around), naming the digit; 4 mm off already is.
  const MergedArrays& m = fixture_merged();
  for (const double dy : {-12.0, -4.0, 4.0, 8.0, 12.0}) {
    Rig rig = load_rig(kFixture + "rig.json");
    for (auto& j : rig.joints) j.y() += dy;
    const std::string e = input_error_of([&] { build_skin(m.points, rig, SkinOptions{}); });
    EXPECT_NE(e.find("does not fit this scan"), std::string::npos) << dy << ": " << e;
  }
  // The rig as given fits: every digit's links within 1.2 mm of its sections' middle.
  const SkinResult s = build_skin(m.points, load_rig(kFixture + "rig.json"), SkinOptions{});
  for (const auto& t : s.tubes)
    if (t.name != "palm") EXPECT_LT(t.axis_offset_mm, 1.2) << t.name;
}

TEST(SkinMesh, DecimationStopsAtTheBudgetOrTheTolerance) {
  const MergedArrays& m = fixture_merged();
  const Rig rig = load_rig(kFixture + "rig.json");
  const MeshDistance to_truth(load_mesh(kFixture + "truth_skin.ply"));
  // A budget the 0.1 mm tolerance cannot reach (it stops near 8000): decimation stops early,
  // and says so.
  SkinOptions tight;
  tight.max_triangles = 6000;
  tight.decimation_tolerance_mm = 0.1;
  const SkinResult a = build_skin(m.points, rig, tight);
  expect_watertight(a);
  EXPECT_GT(a.health.faces, 6000u);
  EXPECT_LT(a.health.faces, a.triangles_before_decimation);
  ASSERT_FALSE(a.warnings.empty());
  EXPECT_NE(a.warnings.back().find("budget 6000"), std::string::npos) << a.warnings.back();
  // With a looser tolerance the budget is met exactly, still closed and free of folds, and the
  // labels survive the collapses.
  SkinOptions loose = tight;
  loose.decimation_tolerance_mm = 0.5;
  const SkinResult b = build_skin(m.points, rig, loose);
  expect_watertight(b);
  EXPECT_LE(b.health.faces, 6000u);
  EXPECT_GE(b.health.faces, 5990u);
  EXPECT_TRUE(b.warnings.empty()) << b.warnings.front();
  size_t with_ring = 0;
  for (int r : b.vertex_ring) with_ring += r >= 0;
  EXPECT_GT(with_ring, b.vertex_ring.size() / 2);
  const OneWayDistance d = one_way_distance(sample_surface(b.mesh, 1.0), to_truth, fixture_markers(), 7.0);
  EXPECT_LE(d.mean, 0.2);
  // No decimation: every strip triangle kept.
  SkinOptions none;
  none.max_triangles = 0;
  const SkinResult c = build_skin(m.points, rig, none);
  EXPECT_EQ(c.health.faces, c.triangles_before_decimation);
}

TEST(SkinMesh, PlyCarriesTheLabels) {
  const MergedArrays& m = fixture_merged();
  const SkinResult s = build_skin(m.points, load_rig(kFixture + "rig.json"), SkinOptions{});
  const std::string dir = temp_dir("skinply");
  save_skin_ply(dir + "/skin.ply", s);
  const std::string bytes = read_file(dir + "/skin.ply");
  EXPECT_NE(bytes.find("property int bone"), std::string::npos);
  EXPECT_NE(bytes.find("property int ring"), std::string::npos);
  const TriMesh back = load_mesh(dir + "/skin.ply");
  EXPECT_EQ(back.n_vertices(), s.mesh.n_vertices());
  EXPECT_EQ(back.n_faces(), s.mesh.n_faces());
}

TEST(MeshDistanceTools, SamplesCoverTheAreaAndASurfaceIsAtZeroFromItself) {
  TriMesh box;  // the cube [0, 10]³, outward
  std::vector<TriMesh::VertexHandle> v;
  for (int i = 0; i < 8; ++i) v.push_back(box.add_vertex(TriMesh::Point(10.0 * (i & 1), 10.0 * ((i >> 1) & 1), 10.0 * (i >> 2))));
  for (const auto& q : std::vector<std::array<int, 4>>{{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}}) {
    box.add_face(v[q[0]], v[q[1]], v[q[2]]);
    box.add_face(v[q[0]], v[q[2]], v[q[3]]);
  }
  const auto samples = sample_surface(box, 2.0);
  EXPECT_NEAR(static_cast<double>(samples.size()), 1200.0, 2.0);  // 600 mm² × 2
  const MeshDistance d(box);
  const OneWayDistance self = one_way_distance(samples, d);
  EXPECT_LT(self.max, 1e-9);
  std::vector<Eigen::Vector3d> off = samples;
  for (auto& p : off) p *= 1.1;  // up to 1 mm off
  const OneWayDistance o = one_way_distance(off, d, {Eigen::Vector3d(0, 0, 0)}, 3.0);
  EXPECT_GT(o.mean, 0.1);
  EXPECT_LE(o.max, std::sqrt(3.0) + 1e-9);  // a corner moved by (1, 1, 1)
  EXPECT_LT(o.samples, samples.size());  // those within 3 mm of the origin were skipped
}
