// Skin, first steps (issue 5): slicing, nearest-bone segmentation, polar resampling.
#include <gtest/gtest.h>
#include <malloc.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <functional>
#include <cmath>
#include <stdexcept>

#include "core/random.hpp"
#include "register/registration.hpp"
#include "skin/auto_rig.hpp"
#include "skin/baseline.hpp"
#include "skin/profile.hpp"
#include "skin/skin_mesh.hpp"
#include "skin/slices.hpp"
#include "mesh/mesh_distance.hpp"
#include "pipeline/options.hpp"
#include "pipeline/skin_stage.hpp"
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

TEST(SkinBaseline, PclPoissonOnTheFixtureIsWholeAndItsErrorIsMeasured) {
  // The reconstruction a user would otherwise run on the merged cloud; its figures are what
  // the strip skin must beat (docs/skin.md).
  const MergedArrays& m = fixture_merged();
  const BaselineResult b = poisson_baseline(m.points, m.normals);
  const MeshHealth h = mesh_health(b.mesh);
  std::printf("Poisson baseline: %zu faces, %zu dropped, %zu boundary edges, %zu non-manifold vertices, %zu components\n",
              h.faces, b.faces_dropped, h.boundary_edges, h.nonmanifold_vertices, h.components);
  // PCL's Poisson is a third party's surface: closed on this cloud until 2026-11-25, when the
  // registration moved the back scan by 0.02 mm and its marching cubes left out one triangle
  // (3 open edges, nothing dropped by us). A hole of a few triangles is its own; more is ours.
  EXPECT_LE(h.boundary_edges, 6u);
  EXPECT_TRUE(h.manifold());
  EXPECT_EQ(h.components, 1u);
  EXPECT_GT(h.volume_mm3, 0.0);
  const Mesh truth = load_mesh(kFixture + "truth_skin.ply");
  const MeshDistance to_baseline(b.mesh);
  size_t within = 0;
  for (const Eigen::Vector3d& p : truth.vertices) within += to_baseline.distance(p) <= 1.0;
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
  const Mesh truth = load_mesh(kFixture + "truth_skin.ply");
  const MeshDistance to_truth(truth), to_skin(s.mesh);
  const auto markers = fixture_markers();
  const OneWayDistance a = one_way_distance(sample_surface(s.mesh, 2.0), to_truth, markers, 7.0);
  const OneWayDistance b = one_way_distance(sample_surface(truth, 2.0), to_skin, markers, 7.0);
  EXPECT_LE(a.mean, 0.15);   // measured 0.10
  EXPECT_LE(a.p95, 0.5);     // measured 0.34
  EXPECT_GE(b.within_1mm, 0.98);  // measured 0.993
}

TEST(SkinMesh, AutomaticSkeletonWithinOneAndAHalfMmOfTheTrueRig) {
  const MergedArrays& m = fixture_merged();
  const AutoRig a = place_skeleton(m.points, m.sides);
  const JointError e = joint_error(a.rig, load_rig(kFixture + "rig.json"));
  std::printf("automatic skeleton on the fixture: mean joint error %.2f mm, worst %s %.2f mm\n", e.mean_mm,
              e.worst_joint.c_str(), e.max_mm);
  EXPECT_LE(e.mean_mm, 1.5) << "worst " << e.worst_joint << " " << e.max_mm;  // measured 1.12
  EXPECT_LE(e.max_mm, 6.0);
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

TEST(SkinMesh, WorkBesideTheFirstStepsRunsOnceAndLeavesTheSkinAsItWas) {
  // build_skin's `beside` (the skin stage's check of a given rig, its sections, the run's
  // picture of the merged cloud) runs once on the other thread, also when the steps throw,
  // and the skin is the same bytes as without it.
  const MergedArrays& m = fixture_merged();
  const Rig rig = load_rig(kFixture + "rig.json");
  std::atomic<int> runs{0};
  const SkinResult alone = build_skin(m.points, rig, SkinOptions{});
  const SkinResult with = build_skin(m.points, rig, SkinOptions{}, {}, [&] { ++runs; });
  EXPECT_EQ(runs.load(), 1);
  EXPECT_EQ(with.mesh.vertices, alone.mesh.vertices);
  EXPECT_EQ(with.mesh.faces, alone.mesh.faces);
  EXPECT_EQ(with.vertex_bone, alone.vertex_bone);
  // The steps' error is the one thrown, after the work beside them ran.
  Rig far = rig;
  for (auto& j : far.joints) j += Eigen::Vector3d(400, 0, 0);
  const std::string e = input_error_of([&] { build_skin(m.points, far, SkinOptions{}, {}, [&] { ++runs; }); });
  EXPECT_NE(e.find("outside the merged cloud"), std::string::npos) << e;
  EXPECT_EQ(runs.load(), 2);
  // The work's own error, when the steps succeed, is thrown too (not lost in its thread).
  EXPECT_THROW(build_skin(m.points, rig, SkinOptions{}, {}, [] { throw std::runtime_error("beside"); }),
               std::runtime_error);
}

TEST(SkinMesh, RigShiftedSidewaysIsRefusedAndTheErrorNamesTheDigit) {
  // A rig shifted sideways does not fit: some digit's links lie beside the middle of its
  // sections. Refused (not worked around), naming the digit; 4 mm off already is.
  const MergedArrays& m = fixture_merged();
  // So is it when given (held to every section as it shows the middle, one-sided ones too).
  SkinOptions given;
  given.rig_given = true;
  for (const double dy : {-12.0, -4.0, 4.0, 8.0, 12.0})
    for (const SkinOptions& o : {SkinOptions{}, given}) {
      Rig rig = load_rig(kFixture + "rig.json");
      for (auto& j : rig.joints) j.y() += dy;
      const std::string e = input_error_of([&] { build_skin(m.points, rig, o); });
      EXPECT_NE(e.find("does not fit this scan"), std::string::npos) << dy << (o.rig_given ? " given" : "") << ": " << e;
    }
  // Through the stage, the error names the rig's file, the causes a user can act on (a rig
  // placed by hand off the digits' axes among them) and the way on without it.
  SkinStageInputs in;
  in.points = m.points, in.normals = m.normals, in.sides = m.sides;
  in.rig = load_rig(kFixture + "rig.json");
  for (auto& j : in.rig->joints) j.y() += 4.0;
  in.rig_name = "hand_rig.json";
  in.slices = false;
  const std::string why = input_error_of([&] { run_skin_stage(in, PipelineOptions{}, [](const std::string&) {}); });
  EXPECT_EQ(why.rfind("hand_rig.json: ", 0), 0u) << why;
  EXPECT_NE(why.find("placed off the digits' axes"), std::string::npos) << why;
  EXPECT_NE(why.find("--auto-rig"), std::string::npos) << why;
  // The rig as given fits: every digit's links within 1.2 mm of its sections' middle.
  const SkinResult s = build_skin(m.points, load_rig(kFixture + "rig.json"), SkinOptions{});
  for (const auto& t : s.tubes)
    if (t.name != "palm") {
      EXPECT_LT(t.axis_offset_mm, 1.2) << t.name;
    }
}

TEST(SkinMesh, APlacedDigitBesideItsSectionsIsMovedOntoThem) {
  // The skin stage's last try for a skeleton it placed: the digits whose links lie off their
  // sections' middles, moved onto them. The fixture's rig with its thumb's MCP, IP and tip and
  // its ring finger's PIP, DIP and tip 4 mm aside is refused; centred, it is taken, those
  // joints come back near the rig's, and the other digits' joints stay as they were.
  const MergedArrays& m = fixture_merged();
  const Rig rig = load_rig(kFixture + "rig.json");
  EXPECT_FALSE(centre_digit_links(m.points, rig, SkinOptions{}).has_value()) << "a rig that fits is not moved";
  Rig off = rig;
  const auto thumb = finger_chain(Finger::Thumb), ring = finger_chain(Finger::Ring);
  for (size_t k = 1; k < thumb.size(); ++k) off.joints[thumb[k]].y() += 4.0;
  for (size_t k = 2; k < ring.size(); ++k) off.joints[ring[k]].y() -= 4.0;
  const std::string e = input_error_of([&] { build_skin(m.points, off, SkinOptions{}); });
  EXPECT_NE(e.find("does not fit this scan"), std::string::npos) << e;
  const std::optional<Rig> centred = centre_digit_links(m.points, off, SkinOptions{});
  ASSERT_TRUE(centred.has_value());
  const SkinResult s = build_skin(m.points, *centred, SkinOptions{});
  EXPECT_TRUE(s.watertight());
  for (const auto& t : s.tubes)
    if (t.name != "palm") {
      EXPECT_LT(t.axis_offset_mm, 1.5) << t.name;
    }
  // Sections tell where a link lies across itself, not along: each moved joint is measured
  // square to the rig's link that ends at it.
  auto across = [&](const std::vector<int>& chain, size_t k) {
    const Eigen::Vector3d dir = (rig.joints[chain[k]] - rig.joints[chain[k - 1]]).normalized();
    const Eigen::Vector3d r = centred->joints[chain[k]] - rig.joints[chain[k]];
    return (r - r.dot(dir) * dir).norm();
  };
  // (The tip lies beyond the last section, at the end of its link's line through them.)
  for (size_t k = 1; k < thumb.size(); ++k) EXPECT_LT(across(thumb, k), k + 1 < thumb.size() ? 1.2 : 1.5) << joints()[thumb[k]].name;
  for (size_t k = 2; k < ring.size(); ++k) EXPECT_LT(across(ring, k), k + 1 < ring.size() ? 1.2 : 1.5) << joints()[ring[k]].name;
  for (int j = 0; j < kJointCount; ++j) {
    const bool moved = std::find(thumb.begin() + 1, thumb.end(), j) != thumb.end() ||
                       std::find(ring.begin() + 2, ring.end(), j) != ring.end();
    if (!moved) {
      EXPECT_EQ(centred->joints[j], off.joints[j]) << joints()[j].name;
    }
  }
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

// The skin in memory — what the patches, the binding and the report measure — is the skin as
// skin.ply holds it, bit for bit (its coordinates rounded to single precision in the build).
TEST(SkinMesh, PlyCarriesTheLabelsAndIsTheSkinInMemory) {
  const MergedArrays& m = fixture_merged();
  const SkinResult s = build_skin(m.points, load_rig(kFixture + "rig.json"), SkinOptions{});
  const std::string dir = temp_dir("skinply");
  save_skin_ply(dir + "/skin.ply", s);
  const std::string bytes = read_file(dir + "/skin.ply");
  EXPECT_NE(bytes.find("property int bone"), std::string::npos);
  EXPECT_NE(bytes.find("property int ring"), std::string::npos);
  const Mesh back = load_mesh(dir + "/skin.ply");
  ASSERT_EQ(back.n_vertices(), s.mesh.n_vertices());
  EXPECT_EQ(back.faces, s.mesh.faces);
  size_t differ = 0;
  for (size_t k = 0; k < back.n_vertices(); ++k) differ += back.vertices[k] != s.mesh.vertices[k];
  EXPECT_EQ(differ, 0u) << "of " << back.n_vertices() << " vertices differ from skin.ply's";
}

TEST(MeshDistanceTools, SamplesCoverTheAreaAndASurfaceIsAtZeroFromItself) {
  Mesh box;  // the cube [0, 10]³, outward
  for (int i = 0; i < 8; ++i) box.vertices.emplace_back(10.0 * (i & 1), 10.0 * ((i >> 1) & 1), 10.0 * (i >> 2));
  for (const auto& q : std::vector<std::array<int, 4>>{{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}}) {
    box.faces.push_back({q[0], q[1], q[2]});
    box.faces.push_back({q[0], q[2], q[3]});
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

// ---------------- the skin stage's steps (skin/skin_steps.hpp) ----------------
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Subdivision_method_3/subdivision_methods_3.h>
#include <CGAL/boost/graph/generators.h>

#include "mesh/from_cgal.hpp"
#include "skin/skin_steps.hpp"

namespace {
using namespace skin_steps;

// A straight tube along X: stations every `h` mm from x = 0 to `length`, points on a circle
// of `radius` about the X axis (noise `sigma`), `n` per mm of length.
TubeBuild cylinder_tube(double length, double radius, double h, double sigma, std::vector<Eigen::Vector3d>* pts) {
  TubeBuild t;
  for (double x = 0; x <= length + 1e-9; x += h) t.st.push_back(frame_at({x, 0, 0}, Eigen::Vector3d::UnitX()));
  Rng rng(7);
  for (double x = -0.4 * h; x <= length + 0.4 * h; x += 0.1)
    for (int j = 0; j < 90; ++j) {
      const double a = 2 * M_PI * (j + rng.uniform(0, 1)) / 90, r = radius + sigma * rng.normal();
      pts->emplace_back(x, r * std::cos(a), r * std::sin(a));
    }
  return t;
}
}  // namespace

TEST(SkinSteps, EveryPointGoesToATubeAndThumbAndPalmShareTheirBoundary) {
  const MergedArrays& m = fixture_merged();
  const Rig rig = load_rig(kFixture + "rig.json");
  const HandFrame H = to_hand_frame(m.points, rig, bones_from_rig(rig));
  const TubePoints P = assign_points(H, 3.0);
  size_t own = 0;
  for (int t = 0; t < kSkinTubes; ++t) {
    EXPECT_GT(P.tube[t].size(), 2000u) << skin_tube_name(t);
    own += P.tube[t].size();
  }
  EXPECT_GT(own, m.points.size());  // the shared band counts twice
  EXPECT_LT(own, m.points.size() + m.points.size() / 10);
  const TubePoints none = assign_points(H, 0.0);
  size_t total = 0;
  for (const auto& t : none.tube) total += t.size();
  EXPECT_EQ(total, m.points.size());  // without the band, each point once
  EXPECT_LT(none.palm.size(), P.palm.size());
}

TEST(SkinSteps, WebsLieBetweenTheKnucklesAndTheMiddleJoints) {
  const MergedArrays& m = fixture_merged();
  const Rig rig = load_rig(kFixture + "rig.json");
  const HandFrame H = to_hand_frame(m.points, rig, bones_from_rig(rig));
  const Webs w = find_webs(H, 4.0);
  ASSERT_EQ(w.points.size(), 3u);
  EXPECT_TRUE(w.warnings.empty());
  for (int f = 1; f <= 3; ++f) {
    const auto a = finger_chain(static_cast<Finger>(f)), b = finger_chain(static_cast<Finger>(f + 1));
    const double mcp = 0.5 * (H.J[a[1]].x() + H.J[b[1]].x()), pip = 0.5 * (H.J[a[2]].x() + H.J[b[2]].x());
    EXPECT_GT(w.points[f - 1].x(), mcp) << f;
    EXPECT_LT(w.points[f - 1].x(), pip) << f;
  }
  EXPECT_LT(w.x_end, 0.5 * (H.J[finger_chain(Finger::Middle)[1]].x() + H.J[finger_chain(Finger::Middle)[2]].x()));
  EXPECT_LE(std::abs(w.alpha_end), 35 * M_PI / 180 + 1e-12);
}

TEST(SkinSteps, WebsEndWhereTheSkinStopsJoiningCloseFingers) {
  // Four fingers (cylinders of radius 8 along +X, from their MCPs at x = 0 to their PIPs at
  // x = 45) whose sides are 1.5 mm apart, joined by webs (an 8 mm thick sheet) up to x = 15;
  // the palm before x = 0. Seen as the two scanners see it: every surface but the flanks
  // steeper than 72 deg, sampled every 0.5 mm. Past the webs the samples of the fingers' sides
  // lie 1.25 mm from the mid-line, 2.5 mm apart: they are not a web (the search before took
  // them for one).
  const double R = 8, gap = 1.5, web_end = 15, pitch = 2 * R + gap;
  HandFrame H;
  for (int f = 1; f < kFingerCount; ++f) {
    const auto c = finger_chain(static_cast<Finger>(f));
    H.J[c[1]] = Eigen::Vector3d(0, (f - 1) * pitch, 0);
    H.J[c[2]] = Eigen::Vector3d(45, (f - 1) * pitch, 0);
  }
  auto height = [&](double x, double y) {  // the top surface's height, or nothing
    double z = -1;
    const double k = std::round(y / pitch), dy = y - k * pitch;
    if (k >= 0 && k <= 3 && std::abs(dy) < R * std::sin(72 * M_PI / 180)) z = std::sqrt(R * R - dy * dy);
    const bool between = y > -R && y < 3 * pitch + R;
    if (between && (x < 0 || (x < web_end && z < 0))) z = std::max(z, 4.0);  // the palm and the webs
    return z;
  };
  for (double x = -20; x <= 60; x += 0.5)
    for (double y = -12; y <= 3 * pitch + 12; y += 0.5) {
      const double z = height(x, y);
      if (z > 0) H.q.emplace_back(x, y, z), H.q.emplace_back(x, y, -z);
    }
  H.lo = Eigen::Vector3d(-60, -12, -8);
  H.hi = Eigen::Vector3d(60, 3 * pitch + 12, 8);
  const Webs w = find_webs(H, 3.0);
  ASSERT_EQ(w.points.size(), 3u);
  EXPECT_TRUE(w.warnings.empty());
  for (const auto& p : w.points) EXPECT_NEAR(p.x(), web_end, 1.0) << p.transpose();
  EXPECT_LT(w.x_end, web_end);
}

TEST(SkinSteps, DigitPlanesAreSquareToTheirLinksAndOrderedAlongThem) {
  const MergedArrays& m = fixture_merged();
  const Rig rig = load_rig(kFixture + "rig.json");
  const HandFrame H = to_hand_frame(m.points, rig, bones_from_rig(rig));
  const TubePoints P = assign_points(H, 3.0);
  for (int f = 1; f < kFingerCount; ++f) {
    const TubeBuild t = digit_planes(H, P, f, 4.0);
    ASSERT_TRUE(t.report.present) << f;
    ASSERT_GE(t.st.size(), 10u);
    const auto c = finger_chain(static_cast<Finger>(f));
    const Eigen::Vector3d prox = (H.J[c[2]] - H.J[c[1]]).normalized();
    EXPECT_GT(t.st[1].n.dot(prox), 0.99) << f;  // the first planes: square to the proximal phalanx
    for (size_t k = 1; k < t.st.size(); ++k) EXPECT_GT(t.st[k].n.dot(t.st[k].o - t.st[k - 1].o), 0) << f << " " << k;
    EXPECT_LT(t.report.axis_offset_mm, 1.2) << f;
  }
}

namespace {
// A hand frame holding one finger along +X from the origin (the metacarpal 60 mm, the
// phalanges 45, 28 and 24), flexed toward -Z (palmar) by `flex` deg at its metacarpal base,
// MCP, PIP and DIP; every other joint far behind it.
HandFrame curled_finger(Finger f, const std::array<double, 4>& flex) {
  HandFrame H;
  for (auto& j : H.J) j = Eigen::Vector3d(-100, 0, 0);
  const auto c = finger_chain(f);
  const double len[] = {60, 45, 28, 24};
  Eigen::Vector3d p(0, 0, 0), d = Eigen::Vector3d::UnitX();
  H.J[c[0]] = p;
  for (size_t k = 1; k < c.size(); ++k) {
    d = Eigen::AngleAxisd(-flex[k - 1] * M_PI / 180, Eigen::Vector3d::UnitY()) * d;
    p += len[k - 1] * d;
    H.J[c[k]] = p;
  }
  return H;
}

// Points on a tube of radius r round each of the finger's links (n a link, uniform along it and
// round it); `outer`: only those on the union's outer surface (none inside another link's tube).
std::vector<Eigen::Vector3d> finger_tube(const HandFrame& H, Finger f, double r, int n, std::uint64_t seed, bool outer) {
  const auto c = finger_chain(f);
  Rng rng(seed);
  std::vector<Eigen::Vector3d> pts;
  for (size_t k = 1; k + 1 < c.size(); ++k) {
    const Eigen::Vector3d a = H.J[c[k]], b = H.J[c[k + 1]], ax = (b - a).normalized();
    const Eigen::Vector3d u = ax.cross(Eigen::Vector3d::UnitY()).normalized(), v = ax.cross(u);
    for (int i = 0; i < n; ++i) {
      const double t = rng.uniform(0, (b - a).norm()), ang = rng.uniform(0, 2 * M_PI);
      const Eigen::Vector3d q = a + t * ax + r * (std::cos(ang) * u + std::sin(ang) * v);
      bool inside_other = false;
      for (size_t m = 1; outer && m + 1 < c.size(); ++m) {
        if (m == k) continue;
        const Eigen::Vector3d a2 = H.J[c[m]], b2 = H.J[c[m + 1]];
        const double s = std::clamp((q - a2).dot(b2 - a2) / (b2 - a2).squaredNorm(), 0.0, 1.0);
        inside_other |= (q - (a2 + s * (b2 - a2))).norm() < r - 1e-6;
      }
      if (!inside_other) pts.push_back(q);
    }
  }
  return pts;
}
}  // namespace

TEST(SkinSteps, CurledFingerPlanesDoNotCrossInsideTheFinger) {
  // A thick middle finger (radius 9 mm) curled 40 deg at the PIP and 30 deg at the DIP. The
  // planes through a bent joint must turn gradually enough that none crosses the next one
  // inside the finger: no sample lies ahead of one plane and behind the next (such samples
  // fell into the wrong slab on the inside of a curled finger's bends).
  const HandFrame H = curled_finger(Finger::Middle, {0, 0, 40, 30});
  const auto c = finger_chain(Finger::Middle);
  TubePoints P;
  P.tube.resize(kSkinTubes);
  P.tube[1 + static_cast<int>(Finger::Middle)] = finger_tube(H, Finger::Middle, 9.0, 12000, 3, true);  // capsules' union
  const TubeBuild t = digit_planes(H, P, static_cast<int>(Finger::Middle), 2.5);
  ASSERT_TRUE(t.report.present);
  const auto crossings = [&](const std::vector<Station>& st) {
    size_t n = 0;
    for (const auto& q : P.tube[1 + static_cast<int>(Finger::Middle)])
      for (size_t k = 0; k + 1 < st.size(); ++k) n += st[k].n.dot(q - st[k].o) < 0 && st[k + 1].n.dot(q - st[k + 1].o) > 0;
    return n;
  };
  EXPECT_EQ(crossings(t.st), 0u);
  // The same stations turning through each joint within one station's spacing do cross.
  std::vector<Eigen::Vector3d> axis;
  for (size_t k = 1; k < c.size(); ++k) axis.push_back(H.J[c[k]]);
  const Polyline pl(axis);
  const double hs = (t.st[1].o - t.st[0].o).norm();
  std::vector<Station> abrupt;
  for (size_t k = 0; k < t.st.size(); ++k) abrupt.push_back(frame_at(pl.at(k * hs), pl.tangent(k * hs, hs)));
  EXPECT_GT(crossings(abrupt), 50u);  // 86 of the samples
}

TEST(SkinSteps, AFingerCurledPastARightAngleKeepsItsStationsTurnedOneWay) {
  // A finger curled 50, 60 and 40 deg at its MCP, PIP and DIP points its far part back toward
  // the wrist. A station's v is the back of the hand on its plane, which there points palmar:
  // it turned half round between two stations, and the strip between their rings twisted
  // through itself (a little finger at MCP 40, PIP 45 deg folded its tube on its own rig). Every
  // station's v must be the finger's own back, turned with it.
  const HandFrame H = curled_finger(Finger::Ring, {0, 50, 60, 40});
  TubePoints P;
  P.tube.resize(kSkinTubes);
  P.tube[1 + static_cast<int>(Finger::Ring)] = finger_tube(H, Finger::Ring, 8.0, 8000, 5, false);  // radius 8 mm
  const TubeBuild t = digit_planes(H, P, static_cast<int>(Finger::Ring), 2.5);
  ASSERT_TRUE(t.report.present);
  double turned = 0;  // how far the stations turn, deg
  for (size_t k = 0; k < t.st.size(); ++k) {
    const Eigen::Vector3d& n = t.st[k].n;
    // In the XZ plane the finger's back is its direction turned 90 deg toward +Z.
    const Eigen::Vector3d back(-n.z(), 0, n.x());
    EXPECT_GT(t.st[k].v.dot(back), 0.99) << "station " << k;
    turned = std::max(turned, std::acos(std::clamp(n.x(), -1.0, 1.0)) * 180 / M_PI);
  }
  EXPECT_GT(turned, 120.0);  // the stations do go past a right angle
}

TEST(SkinSteps, SectionsSeenFromOneSideDoNotCountAgainstARigThatFits) {
  // A straight middle finger (radius 8 mm, along +X) sampled as the two scanners see it
  // (surface within 72 deg of straight up or down), whose distal part (beyond x = 35 mm, most
  // of its sections) shows only its back:
  // its pad was turned away from the palm scanner, as a bent thumb's or a curled finger's far
  // side is. Those sections' extents stop short of their middles' true places; a rig on the
  // axis must still be taken for one that fits, and one 5 mm to the side must not.
  const auto c = finger_chain(Finger::Middle);
  auto make = [&](double shift) {
    HandFrame H;
    for (auto& j : H.J) j = Eigen::Vector3d(-100, 0, 0);
    const double x[] = {-60, 0, 45, 73, 97};
    for (size_t k = 0; k < c.size(); ++k) H.J[c[k]] = Eigen::Vector3d(x[k], shift, 0);
    return H;
  };
  TubePoints P;
  P.tube.resize(kSkinTubes);
  auto& pts = P.tube[1 + static_cast<int>(Finger::Middle)];
  const double R = 8.0;
  for (double x = 0; x <= 105; x += 0.5)
    for (double a = 0; a < 360; a += 2) {
      const double th = a * M_PI / 180, nz = std::sin(th);
      if (std::abs(nz) < std::cos(72 * M_PI / 180)) continue;  // the flanks neither scanner sees
      if (nz < 0 && x > 35) continue;                             // the pad beyond the PIP, unseen
      pts.emplace_back(x, R * std::cos(th), R * nz);
    }
  const TubeBuild fits = digit_planes(make(0.0), P, static_cast<int>(Finger::Middle), 2.5);
  ASSERT_TRUE(fits.report.present);
  EXPECT_LT(fits.report.axis_offset_mm, 1.0);  // over every section: 5.2 mm (the distal ones)
  EXPECT_NEAR(fits.report.section_radius_mm, R, 1.0);
  const TubeBuild beside = digit_planes(make(5.0), P, static_cast<int>(Finger::Middle), 2.5);
  ASSERT_TRUE(beside.report.present);
  EXPECT_GT(beside.report.axis_offset_mm, 4.0);
  // Held to every section as it shows the middle (a given rig's measure), the one-sided ones
  // by the segment their middle may lie on: the same verdicts (measured 0.045 and 5.045 mm).
  EXPECT_LT(fits.report.axis_offset_seen_mm, 1.0);
  EXPECT_GT(beside.report.axis_offset_seen_mm, 4.0);
}

TEST(SkinSteps, RingsOfANoisyCylinderHaveItsRadiusAndSameCount) {
  std::vector<Eigen::Vector3d> pts;
  TubeBuild t = cylinder_tube(40, 8.0, 2.0, 0.05, &pts);
  fill_slabs(&t, pts, 2.0, false);
  SkinOptions o;
  resample_rings(&t, 20, o, false);
  ASSERT_EQ(t.rings.size(), t.st.size());
  EXPECT_EQ(t.report.measured, static_cast<int>(t.st.size()));
  for (const auto& ring : t.rings) {
    ASSERT_EQ(ring.size(), 20u);
    for (const auto& p : ring) EXPECT_NEAR(std::hypot(p.y(), p.z()), 8.0, 0.05);
  }
  // A gap in the scan: rings without points are filled from their neighbours.
  std::vector<Eigen::Vector3d> holed;
  for (const auto& p : pts)
    if (p.x() < 15 || p.x() > 25) holed.push_back(p);
  TubeBuild u = cylinder_tube(40, 8.0, 2.0, 0.05, &pts);
  fill_slabs(&u, holed, 2.0, false);
  resample_rings(&u, 20, o, false);
  EXPECT_GT(u.report.filled, 0);
  for (const auto& ring : u.rings)
    for (const auto& p : ring) EXPECT_NEAR(std::hypot(p.y(), p.z()), 8.0, 0.1);
}

// A fingertip's dome is made from the tube's last ring while rings are added after it: the
// same dome whether the rings' storage has room or must move (a tube whose rings filled their
// capacity exactly read its rim from freed memory, and a family study crashed on it once with a
// general protection fault; AddressSanitizer names the read, a heap-use-after-free).
TEST(SkinSteps, AFingertipsDomeIsTheSameWhenItsRingsStorageMoves) {
  std::vector<Eigen::Vector3d> pts;
  // 61 rings: their storage (1.4 kB) is freed past glibc's per-thread cache, where M_PERTURB
  // below overwrites it, so that a read of it cannot pass for the rim.
  TubeBuild t = cylinder_tube(30, 7.0, 0.5, 0.05, &pts);
  fill_slabs(&t, pts, 0.5, false);
  for (const auto& p : pts)
    if (p.x() > 30) t.beyond.push_back(p);
  SkinOptions o;
  resample_rings(&t, 20, o, false);
  TubeBuild exact = t, roomy = t;
  exact.rings.shrink_to_fit();
  ASSERT_EQ(exact.rings.capacity(), exact.rings.size());
  roomy.rings.reserve(roomy.rings.size() + 16);
  ASSERT_GT(exact.rings.size() * sizeof(exact.rings[0]), 1100u);  // past the per-thread cache's largest block
  mallopt(M_PERTURB, 0x5a);  // freed memory filled with 0x5a meanwhile
  add_dome(&exact, 20, 6, o);
  mallopt(M_PERTURB, 0);
  add_dome(&roomy, 20, 6, o);
  ASSERT_EQ(exact.rings.size(), t.rings.size() + 6);
  ASSERT_EQ(roomy.rings.size(), exact.rings.size());
  ASSERT_TRUE(exact.pole && roomy.pole);
  EXPECT_EQ(*exact.pole, *roomy.pole);
  const Eigen::Vector3d tip = t.st.back().o;
  for (size_t k = t.rings.size(); k < exact.rings.size(); ++k) {
    ASSERT_EQ(exact.rings[k].size(), 20u) << k;
    for (size_t j = 0; j < 20; ++j) {
      ASSERT_EQ(exact.rings[k][j], roomy.rings[k][j]) << k << " " << j;
      EXPECT_NEAR((exact.rings[k][j] - tip).norm(), 7.0, 1.5) << k << " " << j;  // a dome as wide as the tube
    }
  }
}

namespace {
// A straight palm-like prism along X (rings every 2 mm from x = 0 to 10) whose section is a
// 60 × 20 mm rectangle, with, when `notch`, a slot 4 mm wide cut into it from one side 38 mm
// deep, past the middle: the outline of a palm's last section where a low thumb or a bent
// finger leaves a deep notch in it. 80 points a ring, every corner among them.
TubeBuild prism_tube(bool notch) {
  std::vector<Eigen::Vector2d> corners = {{-30, -10}, {30, -10}, {30, 10}, {-30, 10}};
  if (notch) corners = {{-30, -10}, {30, -10}, {30, -2}, {-8, -2}, {-8, 2}, {30, 2}, {30, 10}, {-30, 10}};
  double perimeter = 0;
  for (size_t k = 0; k < corners.size(); ++k) perimeter += (corners[(k + 1) % corners.size()] - corners[k]).norm();
  std::vector<Eigen::Vector2d> outline;
  for (size_t k = 0; k < corners.size(); ++k) {
    const Eigen::Vector2d a = corners[k], b = corners[(k + 1) % corners.size()];
    const int n = k + 1 == corners.size() ? 80 - static_cast<int>(outline.size())
                                          : std::max(1, static_cast<int>(std::lround(80 * (b - a).norm() / perimeter)));
    for (int j = 0; j < n; ++j) outline.push_back(a + (b - a) * j / n);
  }
  TubeBuild t;
  t.id = 0;
  t.report.present = true;
  for (int k = 0; k <= 5; ++k) {
    std::vector<Eigen::Vector3d> ring;
    for (const auto& q : outline) ring.emplace_back(2.0 * k, q.x(), q.y());
    t.rings.push_back(ring);
    t.ring_station.push_back(k);
    t.ring_centre.emplace_back(2.0 * k, -15, 0);
  }
  return t;
}
}  // namespace

// A palm's last ring with a deep notch in its outline: a fan from the ring's centroid (which
// lies in the notch) over it folded the palm tube into itself, and the skin was refused even
// with the hand's own rig (R02 of `scripts/random_hands_study.py --draw 69`, a low thumb and
// the middle finger bent 40° at its MCP). The open ends are now triangulated on the rings'
// own vertices when the fan folds (with a given rig): a closed prism of the notched section's
// volume. A ring the fan suits keeps its fan (its centroid one more vertex at each end).
TEST(SkinSteps, ANotchedEndRingIsClosedOnItsOwnVertices) {
  for (const bool notch : {false, true}) {
    SCOPED_TRACE(notch ? "notched" : "rectangle");
    const TubeBuild t = prism_tube(notch);
    ASSERT_EQ(t.rings.front().size(), 80u);
    PositionOrigin origin;
    int pockets = 0;
    SM sm;
    ASSERT_NO_THROW(sm = stitch_tubes({t}, Eigen::Isometry3d::Identity(), &origin, &pockets, true));
    EXPECT_TRUE(CGAL::is_closed(sm));
    EXPECT_FALSE(CGAL::Polygon_mesh_processing::does_self_intersect(sm));
    const double area = notch ? 60 * 20 - 38 * 4 : 60 * 20;  // straddle moves the corners a little
    EXPECT_NEAR(CGAL::Polygon_mesh_processing::volume(sm), 10 * area, 0.02 * 10 * area);
    EXPECT_EQ(sm.number_of_vertices(), 6 * 80 + (notch ? 0 : 2));
  }
  // Not mended (an automatic placement's tubes: another placement is tried), the fold is refused.
  PositionOrigin origin;
  int pockets = 0;
  EXPECT_THROW(stitch_tubes({prism_tube(true)}, Eigen::Isometry3d::Identity(), &origin, &pockets, false), TubeFoldsError);
}

namespace {
// An elliptic forearm stub (half-axes 35 x 12 mm) along +X, sawn off by the plane n . p = d,
// as two scanners see it: no samples on the flanks steeper than 72 deg, depth noise.
std::vector<Eigen::Vector3d> sawn_stub(const Eigen::Vector3d& n, double d, double sigma) {
  std::vector<Eigen::Vector3d> pts;
  Rng rng(11);
  for (double y = -35; y <= 35; y += 0.5)
    for (double x = 100; x <= 160; x += 0.5)
      for (int side : {-1, 1}) {
        const double t = y / 35;
        if (1 - t * t <= 0) continue;
        const double z = side * 12 * std::sqrt(1 - t * t);
        // the surface normal's Z share: the flanks neither scanner sees are left out
        const Eigen::Vector3d g(0, 2 * y / (35 * 35), 2 * z / (12 * 12));
        if (std::abs(g.normalized().z()) < std::cos(72 * M_PI / 180)) continue;
        const Eigen::Vector3d p(x, y, z + sigma * rng.normal());
        if (n.dot(p) >= d) pts.push_back(p);
      }
  return pts;
}
}  // namespace

TEST(SkinSteps, WristCutIsFittedToTheCloudsProximalRim) {
  for (const Eigen::Vector3d& axis : {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 1, 0), Eigen::Vector3d(1, 2, 3)}) {
    const Eigen::Vector3d n = Eigen::AngleAxisd(8 * M_PI / 180, axis.normalized()) * Eigen::Vector3d::UnitX();
    const Eigen::Vector3d on(120, 0, 0);
    const auto pts = sawn_stub(n, n.dot(on), 0.05);
    double x0 = 1e300;
    for (const auto& p : pts) x0 = std::min(x0, p.x());
    const WristCut cut = fit_wrist_cut(pts, x0);
    ASSERT_TRUE(cut.fitted) << axis.transpose();
    EXPECT_NEAR(cut.tilt_deg, 8.0, 0.5) << axis.transpose();
    EXPECT_GT(cut.n.dot(n), std::cos(0.5 * M_PI / 180)) << axis.transpose();
    // the rim's samples lie at most a grid step distal of the true cut
    EXPECT_NEAR(cut.d, n.dot(on), 0.4) << axis.transpose();
    EXPECT_LT(cut.rms_mm, 0.4);
  }
  // Sawn square: the cut is square to the axis; too few points: square at the cloud's end.
  const auto square = sawn_stub(Eigen::Vector3d::UnitX(), 110, 0.05);
  const WristCut sq = fit_wrist_cut(square, 110);
  ASSERT_TRUE(sq.fitted);
  EXPECT_LT(sq.tilt_deg, 0.3);
  const WristCut none = fit_wrist_cut({Eigen::Vector3d(1, 2, 3)}, 1);
  EXPECT_FALSE(none.fitted);
  EXPECT_EQ(none.n, Eigen::Vector3d::UnitX());
  EXPECT_EQ(none.d, 1);
}

TEST(SkinSteps, PalmPlanesStartInTheWristCutAndTurnSquareWithoutCrossing) {
  const MergedArrays& m = fixture_merged();
  const Rig rig = load_rig(kFixture + "rig.json");
  const HandFrame H = to_hand_frame(m.points, rig, bones_from_rig(rig));
  const TubePoints P = assign_points(H, 3.0);
  const TubeBuild t = palm_planes(H, P, find_webs(H, 3.7), 3.7);
  ASSERT_TRUE(t.cut.fitted);
  EXPECT_NEAR(t.st.front().n.dot(t.cut.n), 1.0, 1e-9);
  EXPECT_NEAR(t.cut.n.dot(t.st.front().o), t.cut.d, 0.01);
  // every palm point lies distal of the first plane (up to the rim's noise) ...
  size_t proximal = 0;
  for (const auto& p : P.palm) proximal += t.cut.n.dot(p) < t.cut.d - 0.5;
  EXPECT_LT(proximal, P.palm.size() / 1000);
  // ... and neighbouring planes do not cross within the palm's breadth
  for (size_t k = 1; k < t.st.size(); ++k) {
    EXPECT_LE(std::acos(std::min(1.0, t.st[k].n.dot(t.st[k - 1].n))), 2.5 * M_PI / 180 + 1e-9) << k;
    for (double y : {-45.0, 45.0}) {
      const Eigen::Vector3d q = t.st[k].o + y * t.st[k].u;
      EXPECT_GT(t.st[k - 1].n.dot(q - t.st[k - 1].o), 0) << k << " " << y;
    }
  }
}

TEST(SkinSteps, PartlySeenRingsCorrectTheirFillInsteadOfCopyingANeighbour) {
  // A tube of radius 8 that tapers to 6 over its last 10 mm, where only a 120 deg arc is seen
  // (a curled fingertip's last sections: the pad and nothing else). The partial rings keep
  // their measured radii on the arc and scale the filled ones elsewhere: the taper shows.
  auto radius = [](double x) { return x <= 30 ? 8.0 : 8.0 - 0.2 * (x - 30); };
  std::vector<Eigen::Vector3d> pts;
  Rng rng(5);
  for (double x = -0.8; x <= 40.8; x += 0.1)
    for (int j = 0; j < 90; ++j) {
      const double a = 2 * M_PI * (j + rng.uniform(0, 1)) / 90;
      if (x > 31 && a > 2 * M_PI / 3) continue;
      const double r = radius(x) + 0.03 * rng.normal();
      pts.emplace_back(x, r * std::cos(a), r * std::sin(a));
    }
  TubeBuild t;
  for (double x = 0; x <= 40 + 1e-9; x += 2) t.st.push_back(frame_at({x, 0, 0}, Eigen::Vector3d::UnitX()));
  fill_slabs(&t, pts, 2.0, false);
  SkinOptions o;
  resample_rings(&t, 20, o, false);
  EXPECT_GE(t.report.partial, 4);
  EXPECT_EQ(t.report.partial, t.report.filled);
  for (size_t k = 0; k < t.rings.size(); ++k)
    for (const auto& p : t.rings[k]) EXPECT_NEAR(std::hypot(p.y(), p.z()), radius(p.x()), 0.15) << k;
}

TEST(SkinSteps, StitchJoinsCrossingTubesIntoOneClosedSurface) {
  std::vector<Eigen::Vector3d> pa, pb;
  std::vector<TubeBuild> tubes(2);
  tubes[0] = cylinder_tube(60, 12.0, 3.0, 0.0, &pa);
  tubes[1] = cylinder_tube(40, 5.0, 2.0, 0.0, &pb);
  fill_slabs(&tubes[0], pa, 3.0, false);
  fill_slabs(&tubes[1], pb, 2.0, false);
  SkinOptions o;
  resample_rings(&tubes[0], 40, o, false);
  resample_rings(&tubes[1], 20, o, false);
  tubes[1].id = 2;
  // The thin tube turned to stick out of the thick one's side.
  // (Off every symmetry: tilted and lifted a little, so that no vertex meets a face exactly.)
  const Eigen::Isometry3d turn = Eigen::Translation3d(30.3, 0, 0.37) *
                                 Eigen::AngleAxisd(1.4, Eigen::Vector3d(0.1, 0, 1).normalized()) *
                                 Eigen::Translation3d(-5, 0, 0);
  for (auto& ring : tubes[1].rings)
    for (auto& p : ring) p = turn * p;
  for (auto& c : tubes[1].ring_centre) c = turn * c;
  skin_steps::PositionOrigin origin;
  int pockets = -1;
  SM sm = stitch_tubes(tubes, Eigen::Isometry3d::Identity(), &origin, &pockets, false);
  EXPECT_TRUE(CGAL::is_closed(sm));
  EXPECT_EQ(pockets, 0);
  EXPECT_FALSE(CGAL::Polygon_mesh_processing::does_self_intersect(sm));
  EXPECT_GT(origin.size(), 100u);
}

// A sphere about the origin: an icosahedron Loop-subdivided `levels` times, every vertex put
// back on the sphere (the chords lie inside it).
static SM sphere_mesh(double radius, int levels) {
  SM m;
  CGAL::make_icosahedron(m, K::Point_3(0, 0, 0), radius);
  for (int k = 0; k < levels; ++k) {
    CGAL::Subdivision_method_3::Loop_subdivision(m, CGAL::parameters::number_of_iterations(1));
    for (auto v : m.vertices()) {
      const K::Vector_3 d = m.point(v) - CGAL::ORIGIN;
      m.point(v) = CGAL::ORIGIN + d * (radius / std::sqrt(d.squared_length()));
    }
  }
  return m;
}

TEST(SkinSteps, FitToDataFollowsTheCloudsSurfaceAndBridgesItsHoleSmoothly) {
  // A coarse sphere of radius 10 (an icosahedron subdivided twice, its vertices on the sphere:
  // the chords lie inside) and the data: a sphere of radius 10.6 with 0.07 mm noise, with no
  // points over the cap z > 8 (a hole) and a few far points (another surface 5 mm out).
  SM sm = sphere_mesh(10.0, 2);
  Rng rng(7);
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 20000; ++i) {
    const Eigen::Vector3d d = Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal()).normalized();
    if (10.6 * d.z() > 8) continue;
    pts.push_back(d * (10.6 + 0.07 * rng.normal()));
    if (i % 50 == 0) pts.push_back(d * 15.6);
  }
  std::vector<K::Point_3> rest;
  for (auto v : sm.vertices()) rest.push_back(sm.point(v));
  const auto mean_distance = [&](const SM& m) {
    const MeshDistance d(to_mesh(m));
    double sum = 0;
    size_t n = 0;
    for (const auto& p : pts)
      if (p.norm() < 12) sum += d.distance(p), ++n;
    return sum / static_cast<double>(n);
  };
  const double before = mean_distance(sm);
  DataFitOptions o;
  const DataFit f = fit_to_data(&sm, pts, o);
  const Crossings c = take_back_crossings(&sm, rest);
  const double after = mean_distance(sm);
  std::printf("data to the sphere: %.3f -> %.3f mm; %zu vertices moved, mean %.3f, max %.3f mm, %zu taken back\n", before,
              after, f.moved, f.mean_move_mm, f.max_move_mm, c.reverted);
  EXPECT_GT(before, 0.6);
  EXPECT_LT(after, 0.1);  // the noise's mean absolute value is 0.056
  EXPECT_FALSE(c.self_intersects);
  EXPECT_LE(f.max_move_mm, o.max_move_mm + 1e-9);
  // The vertices moved out by about 0.6 (a little more: the chords between them reach out to
  // the surface). Over the hole, where no point pulls, the edge term carries the rim's move
  // on smoothly (no dent, no spike); the far points pulled nothing.
  size_t i = 0;
  for (auto v : sm.vertices()) {
    const double r = std::sqrt((sm.point(v) - CGAL::ORIGIN).squared_length()), z = rest[i++].z();
    EXPECT_NEAR(r, 10.7, z < 6 ? 0.1 : 0.25) << z;
  }
  // Only points farther than max_move from the skin: nothing moves.
  SM again;
  CGAL::make_icosahedron(again, K::Point_3(0, 0, 0), 10.0);
  std::vector<Eigen::Vector3d> far;
  for (const auto& p : pts) far.push_back(p.normalized() * 20.0);
  EXPECT_EQ(fit_to_data(&again, far, o).moved, 0u);
  // Off: nothing moves.
  o.enabled = false;
  EXPECT_EQ(fit_to_data(&again, pts, o).moved, 0u);
}

TEST(SkinSteps, FairUnseenSmoothsAnUnseenPitAndLeavesTheSeenSkinAndSmoothUnseenSkinAlone) {
  // A sphere of radius 10 (an icosahedron subdivided three times, ~1.3 mm edges) with a
  // conical pit 3 mm deep over the cap within 25° of +Z, as the union leaves a V between two
  // tubes; the cloud: the true sphere, seen everywhere but within 32° of +Z.
  const auto sphere = [] { return sphere_mesh(10.0, 3); };
  const auto angle_deg = [](const K::Point_3& p) {
    return std::acos(std::clamp(p.z() / std::sqrt((p - CGAL::ORIGIN).squared_length()), -1.0, 1.0)) * 180 / M_PI;
  };
  SM sm = sphere();
  for (auto v : sm.vertices()) {
    const double a = angle_deg(sm.point(v));
    if (a < 25) sm.point(v) = CGAL::ORIGIN + (sm.point(v) - CGAL::ORIGIN) * ((10.0 - 3.0 * (1 - a / 25)) / 10.0);
  }
  Rng rng(3);
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 40000; ++i) {
    const Eigen::Vector3d d = Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal()).normalized();
    if (std::acos(d.z()) * 180 / M_PI > 32) pts.push_back(10.0 * d);
  }
  const Eigen::Vector3d far_cut(1, 0, 0);  // a wrist cut 100 mm away: holds nothing
  std::vector<K::Point_3> was;
  for (auto v : sm.vertices()) was.push_back(sm.point(v));
  const auto worst_radial = [](const SM& m) {
    double w = 0;
    for (auto v : m.vertices()) w = std::max(w, std::abs(std::sqrt((m.point(v) - CGAL::ORIGIN).squared_length()) - 10.0));
    return w;
  };
  FairUnseenOptions o;
  SM faired = sm;
  const FairUnseen f = fair_unseen(&faired, pts, far_cut, -100, o);
  std::printf("pit: %zu crease vertices, %zu faired, mean move %.3f, max %.3f mm; worst radial error %.3f -> %.3f mm\n",
              f.crease_vertices, f.faired, f.mean_move_mm, f.max_move_mm, worst_radial(sm), worst_radial(faired));
  EXPECT_GT(f.crease_vertices, 0u);
  EXPECT_NEAR(worst_radial(sm), 3.0, 1e-9);
  EXPECT_LT(worst_radial(faired), 0.5);  // the pit's floor rises to about the sphere
  size_t i = 0, seen_moved = 0;
  for (auto v : faired.vertices()) {
    if (angle_deg(was[i]) > 40 && faired.point(v) != was[i]) ++seen_moved;
    ++i;
  }
  EXPECT_EQ(seen_moved, 0u);  // the seen skin stays, bit for bit
  // The same unseen cap without the pit has no concave crease: nothing moves.
  SM smooth = sphere();
  const FairUnseen g = fair_unseen(&smooth, pts, far_cut, -100, o);
  EXPECT_EQ(g.crease_vertices, 0u);
  EXPECT_EQ(g.faired, 0u);
  // Everything on the near side of the wrist cut (here the plane Z = 20) is held; off: nothing moves.
  SM held = sm;
  EXPECT_EQ(fair_unseen(&held, pts, Eigen::Vector3d(0, 0, 1), 20, o).faired, 0u);
  o.enabled = false;
  EXPECT_EQ(fair_unseen(&held, pts, far_cut, -100, o).faired, 0u);
}

TEST(SkinMesh, RingGridIsRegularPerTube) {
  const MergedArrays& m = fixture_merged();
  const SkinResult s = build_skin(m.points, load_rig(kFixture + "rig.json"), SkinOptions{});
  ASSERT_EQ(s.grid.size(), static_cast<size_t>(kSkinTubes));
  for (int t = 0; t < kSkinTubes; ++t) {
    const RingGrid& g = s.grid[t];
    EXPECT_EQ(g.tube, t);
    ASSERT_TRUE(g.present);
    ASSERT_GE(g.rings.size(), 10u);
    const size_t M = t == 0 ? 80 : 20;  // 8 and 2 arcs of points_per_segment (10)
    for (const auto& ring : g.rings) EXPECT_EQ(ring.size(), M) << skin_tube_name(t);
    EXPECT_EQ(g.station.size(), g.rings.size());
    EXPECT_EQ(g.pole.has_value(), t != 0);
    // Plane rings first, in plane order; then a digit's dome rings (station -1).
    for (size_t k = 1; k < g.station.size(); ++k)
      if (g.station[k] >= 0) {
        EXPECT_EQ(g.station[k], g.station[k - 1] + 1);
      }
  }
}

namespace {
// A closed convex section sampled every 0.1 mm along its contour, as a radial profile about
// the origin, with the arc |φ| < half_gap left unseen (the flank neither scan saw).
handskin::profile::Profile section_without(const std::vector<Eigen::Vector2d>& contour, double half_gap) {
  std::vector<std::pair<double, double>> pr;
  for (const auto& q : contour) {
    const double a = handskin::profile::wrap(std::atan2(q.y(), q.x()));
    if (a < half_gap || a > handskin::profile::kTwoPi - half_gap) continue;
    pr.emplace_back(a, q.norm());
  }
  std::sort(pr.begin(), pr.end());
  handskin::profile::Profile P;
  for (const auto& [a, r] : pr) P.phi.push_back(a), P.rho.push_back(r);
  return P;
}
std::vector<Eigen::Vector2d> walk(const std::function<Eigen::Vector2d(double)>& at, double length) {
  std::vector<Eigen::Vector2d> out;
  const int n = static_cast<int>(length / 0.1);
  for (int k = 0; k < n; ++k) out.push_back(at(static_cast<double>(k) / n));
  return out;
}
// The ellipse with half-axes a (along x) and b, walked from (a, 0); `length` about its perimeter.
std::vector<Eigen::Vector2d> ellipse(double a, double b, double length) {
  return walk([a, b](double u) { return Eigen::Vector2d(a * std::cos(2 * M_PI * u), b * std::sin(2 * M_PI * u)); }, length);
}
}  // namespace

// The bridge across an unseen arc must suit both shapes a hand shows there: a flat middle
// between rounder ends (a thumb turned about its axis, nail or pad facing sideways: the circle
// through the sides' samples bulged 0.6 mm out there on the WebXR hand) and a curvature peak
// inside the gap (the edge of a section wider than it is thick).
TEST(SkinProfile, BridgeAcrossAnUnseenArcSuitsFlatAndPointedMiddles) {
  // Rounded rectangle, half-sizes 6 × 7 mm, corners of 5 mm: the gap (±24°) is its flat side
  // x = 6 and the start of its corners; the samples beside it turn round the corners.
  const double a = 6, b = 7, rc = 5;
  const double fx = b - rc, fy = a - rc;  // straight half-lengths of the x = ±a and y = ±b sides
  const double perimeter = 4 * (fx + fy) + 2 * M_PI * rc;
  auto rounded = [&](double u) {
    double s = u * perimeter;
    // Counter-clockwise from (a, 0): side x = a up, corner, side y = b leftward, ...
    const std::array<Eigen::Vector2d, 4> corner = {Eigen::Vector2d(a - rc, b - rc), Eigen::Vector2d(-(a - rc), b - rc),
                                                   Eigen::Vector2d(-(a - rc), -(b - rc)), Eigen::Vector2d(a - rc, -(b - rc))};
    const std::array<double, 4> straight = {fx, 2 * fy, 2 * fx, 2 * fy};
    if (s < fx) return Eigen::Vector2d(a, s);
    s -= fx;
    for (int k = 0; k < 4; ++k) {
      const double arc = 0.5 * M_PI * rc;
      const double start = 0.5 * M_PI * k;
      if (s < arc) return Eigen::Vector2d(corner[k] + rc * Eigen::Vector2d(std::cos(start + s / rc), std::sin(start + s / rc)));
      s -= arc;
      const double len = k < 3 ? straight[k + 1] : fx;
      const Eigen::Vector2d from = corner[k] + rc * Eigen::Vector2d(std::cos(start + 0.5 * M_PI), std::sin(start + 0.5 * M_PI));
      const Eigen::Vector2d dir(std::cos(start + M_PI), std::sin(start + M_PI));
      if (s < len) return Eigen::Vector2d(from + s * dir);
      s -= len;
    }
    return Eigen::Vector2d(a, 0);
  };
  const auto flat = section_without(walk(rounded, perimeter), 24 * M_PI / 180);
  // Ellipse 8 × 5.5 mm, the gap (±28°) round the end of its long axis.
  const auto pointed = section_without(ellipse(8, 5.5, 43.0), 28 * M_PI / 180);
  const double window = 2 * M_PI / 180, bridge = 0.2;
  double worst_flat = 0, worst_pointed = 0;
  for (double deg = -15; deg <= 15; deg += 5) {
    const double p = deg * M_PI / 180;
    // The true radii there: the flat side x = a (within its straight part), the ellipse's.
    const double true_flat = a / std::cos(p);
    const double true_pointed = 1 / std::sqrt(std::pow(std::cos(p) / 8, 2) + std::pow(std::sin(p) / 5.5, 2));
    worst_flat = std::max(worst_flat, std::abs(flat.at_bridged(p, window, bridge) - true_flat));
    worst_pointed = std::max(worst_pointed, std::abs(pointed.at_bridged(p, window, bridge) - true_pointed));
  }
  std::printf("bridge error: flat middle %.3f mm, pointed middle %.3f mm\n", worst_flat, worst_pointed);
  // The circle through the sides' samples alone (the bridge before): 0.66 and 0.89 mm.
  EXPECT_LT(worst_flat, 0.5);
  EXPECT_LT(worst_pointed, 0.6);
  // Where both guesses are right, so is their mean: a circle of 7 mm, a ±30° gap.
  const auto round = section_without(ellipse(7, 7, 44.0), 30 * M_PI / 180);
  for (double deg = -20; deg <= 20; deg += 5) EXPECT_NEAR(round.at_bridged(deg * M_PI / 180, window, bridge), 7.0, 0.02);
}

TEST(SkinProfile, BridgeAcrossHalfTheRingStaysRound) {
  // A curled fingertip cut at a slant by the automatic skeleton's planes: half its section
  // (the pad) unseen. A circle's arc across half a turn bulges half its chord; the bridge
  // took that for a wild guess and fell back to the chord, which runs through the centre:
  // the radius dropped to the ring's floor and the pad got a 5 mm notch (H05, automatic).
  const double window = 2 * M_PI / 180, bridge = 0.2;
  for (const double half_gap_deg : {90.0, 110.0}) {
    const auto round = section_without(ellipse(7, 7, 44.0), half_gap_deg * M_PI / 180);
    double worst = 0;
    for (double deg = -half_gap_deg + 10; deg <= half_gap_deg - 10; deg += 10)
      worst = std::max(worst, std::abs(round.at_bridged(deg * M_PI / 180, window, bridge) - 7.0));
    EXPECT_LT(worst, 0.3) << "a circle of 7 mm with " << 2 * half_gap_deg << "° unseen";
  }
  // An ellipse 5.5 × 8 mm with the half beyond its short axis unseen: both guesses round it
  // off at the radius of the gap's ends (8 mm where the truth is 5.5: the seen half says
  // nothing of how flat the other is), never the chord's radius near zero (before: 0.0).
  const auto oval = section_without(ellipse(5.5, 8, 43.0), M_PI / 2);
  for (double deg = -80; deg <= 80; deg += 10) {
    const double p = deg * M_PI / 180;
    const double truth = 1 / std::sqrt(std::pow(std::cos(p) / 5.5, 2) + std::pow(std::sin(p) / 8, 2));
    const double r = oval.at_bridged(p, window, bridge);
    EXPECT_GT(r, 0.9 * truth) << deg << "°";
    EXPECT_LT(r, 1.5 * truth) << deg << "°";
  }
}
