// Registration: table removal, marker spheres, matching, refinement and the whole stage
// against synthetic scans whose true transform is known.
#include <ceres/rotation.h>
#include <gtest/gtest.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cmath>
#include <functional>
#include <limits>
#include <cstdio>

#include "core/errors.hpp"
#include "core/json_util.hpp"
#include "core/random.hpp"
#include "core/transform.hpp"
#include "pipeline/registration_stage.hpp"
#include "register/refine.hpp"
#include "register/registration.hpp"
#include "register/small_fit.hpp"
#include "register/sphere_residual.hpp"
#include "synth/replica.hpp"
#include "synth/scanner.hpp"
#include "test_util.hpp"

using namespace handskin;
using test::input_error_of;
using test::add_box;
using test::add_sphere;

namespace {
constexpr double kDeg = M_PI / 180.0;
const std::string kFixture = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";





const RegisterProgress kQuiet = [](const std::string&) {};

// The two hands of the acceptance runs: the fixture's default hand, and a longer, broader,
// thicker one with wider spread meshed here.
struct Hand {
  Mesh mesh;
  Rig rig;
};
const Hand& default_hand() {
  static const Hand h = [] {
    Hand x;
    x.mesh = load_mesh(kFixture + "truth_skin.ply");
    x.rig = load_rig(kFixture + "rig.json");
    return x;
  }();
  return h;
}
const Hand& second_hand() {
  // Meshed by the command in a fresh process: CGAL's mesher repeats exactly only there
  // (docs/synthetic-data.md), so this hand is the same whatever ran before in this test binary.
  static const Hand h = [] {
    const std::string dir = test::temp_dir("hand2");
    std::string out;
    const int rc = test::run(std::string(HANDSKIN_BINARY) +
                                 " -q synth hand --hand-length 200 --width 1.12 --thickness 1.1 --spread 9"
                                 " --thumb-abduction 50 --no-render --out " + dir,
                             &out);
    if (rc != 0) throw std::runtime_error("synth hand failed: " + out);
    Hand x;
    x.mesh = load_mesh(dir + "/hand.ply");
    x.rig = load_rig(dir + "/hand_rig.json");
    return x;
  }();
  return h;
}

struct Outcome {
  RegistrationError chosen, marker_only;
  Registration reg;
};

Outcome register_pair(const Hand& hand, std::uint64_t seed, const ReplicaOptions& ro, const ScannerOptions& so,
                      const RegistrationOptions& opts = RegistrationOptions{}) {
  const ScanPair pair = synthesize_scan_pair(hand.mesh, hand.rig, ro, so, seed, false);
  Outcome out;
  out.reg = register_scans(pair.back.scan, pair.palm.scan, "back", "palm", opts, nullptr, kQuiet);
  const auto skin = pair.skin_palm.vertices;
  out.chosen = registration_error(out.reg.back_to_palm, pair.back_to_palm, skin);
  out.marker_only = registration_error(out.reg.marker_only, pair.back_to_palm, skin);
  return out;
}

}  // namespace

// ---------------------------------------------------------------- table and speckle

TEST(Prepare, TableRemovedAtAnyHeightAndTilt) {
  for (const auto& [height, tilt] : {std::pair{10.0, 0.0}, {37.0, 3.0}, {5.0, -2.0}}) {
    ScannerOptions so;
    so.table_height_mm = height;
    so.table_tilt_deg = tilt;
    Scene scene;
    const double base = so.table_z(100.0);
    add_box(&scene, {90, 70, base - 5}, {130, 110, base + 20}, 0);
    add_sphere(&scene, {180, 50, so.table_z(180) + 3.2}, 3.0, 1);
    const ScanSimulation sim = simulate_scan(scene, so, ScanSide::Back, 4);
    const PreparedScan p = prepare_scan(sim.scan, PrepareOptions{}, "scan");
    EXPECT_NEAR(p.table_tilt_deg, std::abs(tilt), 0.02) << "height " << height;
    EXPECT_LT(p.table_rms_mm, 0.1);
    // Every kept sample is an object's; every object sample higher than the margin is kept.
    size_t object_high = 0;
    for (int i = 0; i < sim.scan.meta.scanlines; ++i)
      for (int j = 0; j < sim.scan.meta.points; ++j) {
        const size_t px = static_cast<size_t>(i) * sim.scan.meta.points + j;
        const int k = p.point_of_pixel[px];
        if (k >= 0) {
          EXPECT_GE(sim.pixel_object[px], 0) << "a table sample was kept at " << i << "," << j;
        }
        const Eigen::Vector3d q = sim.scan.position(i, j);
        if (sim.pixel_object[px] >= 0 && q.z() - so.table_z(q.x()) > 1.3) {
          ++object_high;
          EXPECT_GE(k, 0) << "an object sample was dropped";
        }
      }
    EXPECT_GT(object_high, 5000u);
  }
}

TEST(Prepare, SpeckleDroppedObjectsKept) {
  ScannerOptions so;
  Scene scene;
  add_box(&scene, {90, 70, 0}, {130, 110, 30}, 0);
  ScanSimulation sim = simulate_scan(scene, so, ScanSide::Back, 5);
  // Stray single returns and a 2x2 clump, 20 mm above the table.
  const std::uint16_t high = static_cast<std::uint16_t>(30.0 / so.z_step_mm);
  const std::vector<std::pair<int, int>> stray = {{20, 20}, {400, 30}, {300, 450}, {50, 400}, {51, 400}, {50, 401}, {51, 401}};
  for (const auto& [i, j] : stray) sim.scan.values[static_cast<size_t>(i) * so.points + j] = high;
  const PreparedScan p = prepare_scan(sim.scan, PrepareOptions{}, "scan");
  EXPECT_EQ(p.speckle_points, stray.size());
  EXPECT_EQ(p.speckle_islands, 4u);
  EXPECT_EQ(p.points.size(), sim.returns_per_object[0] - 0 - [&] {
    size_t low = 0;  // box samples within the margin of the table (its lowest rim) are table
    for (int i = 0; i < so.scanlines; ++i)
      for (int j = 0; j < so.points; ++j) {
        const size_t px = static_cast<size_t>(i) * so.points + j;
        if (sim.pixel_object[px] == 0 && sim.scan.position(i, j).z() - so.table_height_mm <= 1.0) ++low;
      }
    return low;
  }());
}

TEST(Prepare, NoTableOrNoObjectIsAnError) {
  RangeScan empty;
  empty.values.assign(512 * 512, 0);
  EXPECT_NE(input_error_of([&] { prepare_scan(empty, PrepareOptions{}, "e.png"); }).find("e.png"), std::string::npos);
  ScannerOptions so;
  const ScanSimulation bare = simulate_scan(Scene{}, so, ScanSide::Back, 1);
  EXPECT_NE(input_error_of([&] { prepare_scan(bare.scan, PrepareOptions{}, "t.png"); }).find("no object"),
            std::string::npos);
}

// ---------------------------------------------------------------- marker spheres

TEST(Spheres, FindsMarkerSpheresOnlyAndLocatesThem) {
  ScannerOptions so;
  Scene scene;
  // A slab with four 3 mm spheres half embedded in its top and sides, a 7 mm "fingertip",
  // a 1.5 mm pimple and a 4.5 mm knob: only the four are markers.
  add_box(&scene, {60, 50, 0}, {190, 150, 25}, 0);
  const std::vector<Eigen::Vector3d> markers = {{80, 70, 25}, {150, 130, 25.5}, {120, 50, 20}, {190, 100, 18}};
  int id = 1;
  for (const auto& c : markers) add_sphere(&scene, c, 3.0, id++);
  add_sphere(&scene, {110, 110, 22}, 7.0, id++);
  add_sphere(&scene, {170, 70, 25}, 1.5, id++);
  add_sphere(&scene, {100, 130, 25}, 4.5, id++);
  const ScanSimulation sim = simulate_scan(scene, so, ScanSide::Back, 6);
  const PreparedScan p = prepare_scan(sim.scan, PrepareOptions{}, "scan");
  std::vector<SphereCandidateReport> cands;
  SphereOptions three;  // the detector works for whatever radius it is told
  three.radius_mm = 3.0;
  const auto found = detect_spheres(p, three, &cands);
  ASSERT_EQ(found.size(), markers.size());
  for (const auto& c : markers) {
    double best = 1e9;
    for (const auto& f : found) best = std::min(best, (f.centre - c).norm());
    EXPECT_LT(best, 0.06) << "marker at " << c.transpose();
  }
  for (const auto& f : found) {
    EXPECT_NEAR(f.radius_free, 3.0, 0.15);
    EXPECT_LT(f.rms_mm, 0.1);
  }
}

TEST(Spheres, ManualPositionFitsOrSaysWhy) {
  ScannerOptions so;
  Scene scene;
  add_box(&scene, {60, 50, 0}, {190, 150, 25}, 0);
  add_sphere(&scene, {100, 100, 25}, 3.0, 1);
  const PreparedScan p = prepare_scan(simulate_scan(scene, so, ScanSide::Back, 7).scan, PrepareOptions{}, "scan");
  std::string why;
  SphereOptions three;
  three.radius_mm = 3.0;
  const auto f = fit_sphere_near(p, {101.5, 99.0, 26.0}, 3.0, three, &why);
  ASSERT_TRUE(f) << why;
  EXPECT_LT((f->centre - Eigen::Vector3d(100, 100, 25)).norm(), 0.06);
  EXPECT_FALSE(fit_sphere_near(p, {150, 120, 25}, 3.0, three, &why));  // flat top: no sphere
  EXPECT_FALSE(why.empty());
}

// ---------------------------------------------------------------- matching

namespace {
std::vector<Eigen::Vector3d> irregular_pattern(Rng* rng, int n) {
  std::vector<Eigen::Vector3d> v;
  while (static_cast<int>(v.size()) < n) {
    const Eigen::Vector3d c(rng->uniform(0, 150), rng->uniform(0, 80), rng->uniform(0, 30));
    bool ok = true;
    for (const auto& q : v) ok = ok && (q - c).norm() > 10;
    if (ok) v.push_back(c);
  }
  return v;
}
Eigen::Isometry3d turnover(double yaw_deg, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = t;
  return T;
}
}  // namespace

TEST(Match, PermutedNoisyMissingAndSpurious) {
  Rng rng(11);
  for (int trial = 0; trial < 20; ++trial) {
    const auto back = irregular_pattern(&rng, 9);
    const Eigen::Isometry3d T = turnover(rng.uniform(-30, 30), {rng.uniform(0, 50), rng.uniform(0, 50), 40});
    std::vector<int> perm = {4, 0, 7, 2, 8, 1, 6, 3, 5};
    std::vector<Eigen::Vector3d> palm(9);
    for (int k = 0; k < 9; ++k)
      palm[perm[k]] = T * back[k] + Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal()) * 0.03;
    MarkerMatch m = match_markers(back, palm, 0.5);
    ASSERT_EQ(m.pairs.size(), 9u);
    for (const auto& [b, p] : m.pairs) EXPECT_EQ(p, perm[b]);
    EXPECT_LT(rotation_difference_deg(m.back_to_palm, T), 0.1);
    EXPECT_NEAR(m.back_to_palm.linear().determinant(), 1.0, 1e-9);
    EXPECT_LT(m.runner_up_pairs, 9u);

    // One missing on the back, one spurious bump on the palm.
    std::vector<Eigen::Vector3d> back8(back.begin() + 1, back.end());
    std::vector<Eigen::Vector3d> palm10 = palm;
    palm10.push_back(T * Eigen::Vector3d(70, 40, 35));
    m = match_markers(back8, palm10, 0.5);
    ASSERT_EQ(m.pairs.size(), 8u);
    for (const auto& [b, p] : m.pairs) EXPECT_EQ(p, perm[b + 1]);
  }
}

TEST(Match, MirrorAndForeignPatternsDoNotMatch) {
  Rng rng(12);
  const auto back = irregular_pattern(&rng, 9);
  // A mirror image has every distance right, but no proper rotation maps it: only a nearly
  // coplanar subset (whose mirror image is a rotated copy) can pair up, never the pattern.
  std::vector<Eigen::Vector3d> mirrored;
  for (const auto& p : back) mirrored.emplace_back(p.x(), -p.y(), p.z());
  EXPECT_LE(match_markers(back, mirrored, 0.5).pairs.size(), 4u);
  const auto other = irregular_pattern(&rng, 9);
  EXPECT_LT(match_markers(back, other, 0.5).pairs.size(), 4u);
}

TEST(Match, SymmetricPatternIsReportedAmbiguous) {
  // A rectangle's corners plus its centre: a half turn about the centre maps it onto itself.
  const std::vector<Eigen::Vector3d> back = {{0, 0, 0}, {60, 0, 0}, {60, 30, 0}, {0, 30, 0}, {30, 15, 0}};
  const MarkerMatch m = match_markers(back, back, 0.5);
  EXPECT_EQ(m.pairs.size(), 5u);
  EXPECT_EQ(m.runner_up_pairs, 5u);
}

// ---------------------------------------------------------------- refinement

namespace {
// Two scans of the same side of the palm-up replica (fixture skin + markers), with fresh
// noise and the second moved by a small known yaw and shift: the skin overlaps almost
// everywhere, so the gated ICP terms take part.
struct SameSide {
  double radius = 0;
  PreparedScan a, b;
  Eigen::Isometry3d b_to_a;
  std::vector<MarkerSamples> markers;
  std::vector<char> skin_a, skin_b;
};
SameSide same_side_pair() {
  const Json truth = load_json_object(kFixture + "truth.json");
  std::vector<Eigen::Vector3d> marker_c;
  for (const auto& m : truth["markers_palm"]) marker_c.push_back(to_vec3(m, "m", "truth"));
  const double R = get_positive(truth, "marker_radius_mm", "truth");
  Mesh mesh = load_mesh(kFixture + "truth_skin.ply");
  Eigen::Isometry3d move = Eigen::Isometry3d::Identity();
  move.rotate(Eigen::AngleAxisd(2.0 * kDeg, Eigen::Vector3d::UnitZ()));
  move.pretranslate(Eigen::Vector3d(3.0, -2.0, 0.0));
  ScannerOptions so;
  auto scene_for = [&](const Eigen::Isometry3d& T) {
    Scene s;
    std::vector<Eigen::Vector3d> v;
    for (const auto& p : mesh.vertices) v.push_back(T * p);
    s.add(v, mesh.faces, 0);
    for (size_t k = 0; k < marker_c.size(); ++k) add_sphere(&s, T * marker_c[k], R, static_cast<int>(k) + 1);
    return s;
  };
  SameSide out;
  out.radius = R;
  SphereOptions so_r;
  so_r.radius_mm = R;
  out.a = prepare_scan(simulate_scan(scene_for(Eigen::Isometry3d::Identity()), so, ScanSide::Palm, 21).scan,
                       PrepareOptions{}, "a");
  out.b = prepare_scan(simulate_scan(scene_for(move), so, ScanSide::Palm, 22).scan, PrepareOptions{}, "b");
  out.b_to_a = move.inverse();
  const auto fa = detect_spheres(out.a, so_r), fb = detect_spheres(out.b, so_r);
  std::vector<Eigen::Vector3d> ca, cb;
  for (const auto& f : fa) ca.push_back(f.centre);
  for (const auto& f : fb) cb.push_back(f.centre);
  const MarkerMatch m = match_markers(cb, ca, 0.5);
  for (const auto& [ib, ia] : m.pairs) {
    MarkerSamples s;
    for (int k : fb[ib].inliers) s.back.push_back(out.b.points[k]);
    for (int k : fa[ia].inliers) s.palm.push_back(out.a.points[k]);
    out.markers.push_back(s);
  }
  auto mask = [R](const PreparedScan& s, const std::vector<Eigen::Vector3d>& c) {
    std::vector<char> m(s.points.size(), 1);
    for (size_t k = 0; k < s.points.size(); ++k)
      for (const auto& x : c)
        if ((s.points[k] - x).norm() < R + 0.5) m[k] = 0;
    return m;
  };
  out.skin_a = mask(out.a, ca);
  out.skin_b = mask(out.b, cb);
  return out;
}
}  // namespace

// The ICP's correspondence search (GatedNearest) finds what PCL's radius search of one
// neighbour found before it: points on a 0.25 mm grid (so that distances tie exactly), each
// twice (equal points), and scattered ones; queries at grid points, exactly one gate away from
// one (the bound is strict), between grid points, and far from every point.
TEST(Refine, GatedNearestIsPclsRadiusSearchOfOne) {
  Rng rng(7);
  std::vector<float> xyz;
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  const auto add = [&](float x, float y, float z) {
    xyz.insert(xyz.end(), {x, y, z});
    cloud->push_back(pcl::PointXYZ(x, y, z));
  };
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) {
      add(0.25f * i, 0.25f * j, 0.0f);
      add(0.25f * i, 0.25f * j, 0.0f);
    }
  for (int k = 0; k < 3000; ++k)
    add(static_cast<float>(rng.uniform(-5, 10)), static_cast<float>(rng.uniform(-5, 10)), static_cast<float>(rng.uniform(-2, 2)));
  std::vector<float> queries;
  for (int k = 0; k < 4000; ++k) {
    const int kind = k % 4;
    const float gx = 0.25f * static_cast<float>(k % 20), gy = 0.25f * static_cast<float>((k / 20) % 20);
    if (kind == 0) queries.insert(queries.end(), {gx, gy, 0.0f});
    else if (kind == 1) queries.insert(queries.end(), {gx, gy, 0.5f});  // one gate above a grid point
    else if (kind == 2) queries.insert(queries.end(), {gx + 0.125f, gy + 0.125f, 0.1f});
    else queries.insert(queries.end(), {static_cast<float>(rng.uniform(-8, 13)), static_cast<float>(rng.uniform(-8, 13)),
                                        static_cast<float>(rng.uniform(-4, 4))});
  }
  const double gate = 0.5;
  const GatedNearest mine(xyz, gate);
  const std::vector<int> found = mine.find(queries);
  pcl::KdTreeFLANN<pcl::PointXYZ> pcl_tree;
  pcl_tree.setInputCloud(cloud);
  int within = 0, none = 0;
  for (size_t k = 0; k < found.size(); ++k) {
    std::vector<int> idx(1);
    std::vector<float> d2(1);
    const pcl::PointXYZ q(queries[3 * k], queries[3 * k + 1], queries[3 * k + 2]);
    const int expected = pcl_tree.radiusSearch(q, gate, idx, d2, 1) < 1 ? -1 : idx[0];
    ASSERT_EQ(found[k], expected) << "query " << k;
    (expected < 0 ? none : within) += 1;
  }
  EXPECT_GT(within, 1000);
  EXPECT_GT(none, 500);
  EXPECT_EQ(GatedNearest({}, gate).find(queries), std::vector<int>(found.size(), -1));
}

TEST(Refine, GatedIcpPullsAPerturbedFitIn) {
  const SameSide s = same_side_pair();
  ASSERT_GE(s.markers.size(), 8u);
  Eigen::Isometry3d T0 = s.b_to_a;
  T0.prerotate(Eigen::AngleAxisd(0.15 * kDeg, Eigen::Vector3d(1, 1, 0).normalized()));
  T0.pretranslate(Eigen::Vector3d(0.15, -0.1, 0.1));
  const RefineResult r = refine_registration(s.b, s.a, s.skin_b, s.skin_a, s.markers, T0, s.radius, SphereOptions{}.steep_floor, RefineOptions{});
  EXPECT_TRUE(r.accepted) << r.note;
  EXPECT_GT(r.overlap_fraction, 0.5);
  EXPECT_GT(r.iterations, 1);
  EXPECT_LT(r.surface_rms_mm, 0.1);
  EXPECT_LT(rotation_difference_deg(r.T, s.b_to_a), 0.01);
  EXPECT_LT((r.T.translation() - s.b_to_a.translation()).norm(), 0.02);
  EXPECT_LE(r.marker_rms_end, r.marker_rms_start);

  // The guard: a refinement that moves further than allowed is refused.
  RefineOptions strict;
  strict.max_departure_deg = 1e-6;
  const RefineResult g = refine_registration(s.b, s.a, s.skin_b, s.skin_a, s.markers, T0, s.radius, SphereOptions{}.steep_floor, strict);
  EXPECT_FALSE(g.accepted);
  EXPECT_NE(g.note.find("strayed"), std::string::npos) << g.note;
}

// The markers' joint centres with the pose held (marker_sphere_rms, whose centres the pose's
// covariance and registration.json use) by small_fit are where Ceres's own solve of that
// problem ends — each marker's centre against its palm samples and its back samples carried
// through the pose, Ceres's DENSE_QR with the function tolerance 1e-12 that marker_sphere_rms
// gave it — and so is the RMS; the back samples count (a pose 0.3 mm off moves the centres).
TEST(Refine, MarkerCentresWithThePoseHeldAreCeressSolve) {
  const SameSide s = same_side_pair();
  ASSERT_GE(s.markers.size(), 8u);
  const double floor = SphereOptions{}.steep_floor;
  for (const double off_mm : {0.0, 0.3}) {
    Eigen::Isometry3d T = s.b_to_a;
    T.pretranslate(Eigen::Vector3d(off_mm, 0, 0));
    std::vector<Eigen::Vector3d> centres;
    const double rms = marker_sphere_rms(s.markers, T, s.radius, floor, &centres);
    ASSERT_EQ(centres.size(), s.markers.size());
    double pose[6];
    const Eigen::AngleAxisd aa(T.linear());
    for (int k = 0; k < 3; ++k) pose[k] = aa.angle() * aa.axis()(k), pose[3 + k] = T.translation()(k);
    double ss = 0;
    size_t n = 0;
    for (size_t m = 0; m < s.markers.size(); ++m) {
      const MarkerSamples& ms = s.markers[m];
      Eigen::Vector3d start = Eigen::Vector3d::Zero();
      for (const auto& p : ms.palm) start += p;
      for (const auto& p : ms.back) start += T * p;
      start /= static_cast<double>(ms.palm.size() + ms.back.size());
      double c[3] = {start.x(), start.y(), start.z()};
      ceres::Problem problem;
      for (const auto& p : ms.palm) problem.AddResidualBlock(SphereResidual::Create(p, s.radius, floor), nullptr, c);
      for (const auto& p : ms.back)
        problem.AddResidualBlock(BackOnSphere::Create(p, s.radius, floor), nullptr, pose, c);
      if (!ms.back.empty()) problem.SetParameterBlockConstant(pose);
      ceres::Solver::Options o;
      o.linear_solver_type = ceres::DENSE_QR;
      o.logging_type = ceres::SILENT;
      o.max_num_iterations = 50;
      o.function_tolerance = 1e-12;
      ceres::Solver::Summary summary;
      ceres::Solve(o, &problem, &summary);
      ss += 2.0 * summary.final_cost;
      n += ms.palm.size() + ms.back.size();
      EXPECT_GE(summary.iterations.size(), 2u);  // the solve moved
      EXPECT_LT((centres[m] - Eigen::Vector3d(c[0], c[1], c[2])).norm(), 1e-10) << "marker " << m << ", pose off " << off_mm;
    }
    EXPECT_NEAR(rms, std::sqrt(ss / static_cast<double>(n)), 1e-12);
    if (off_mm > 0) EXPECT_GT(rms, 0.1);  // the back samples moved with the pose: the caps no longer agree
  }
}

TEST(Refine, UngatedIcpWouldCollapseTheHandAndIsRefused) {
  // Back and palm scans share almost no surface; closest points across the hand's
  // thickness pull a naive ICP off. With the gates opened wide, the guard must catch it.
  const RangeScan back = load_scan(kFixture + "back"), palm = load_scan(kFixture + "palm");
  RegistrationOptions naive;
  naive.refine.gate_mm = 10.0;
  naive.refine.normal_deg = 90.0;
  naive.refine.trim = 1.0;
  naive.refine.min_surface_pairs = 3;
  const Registration reg = register_scans(back, palm, "back", "palm", naive, nullptr, kQuiet);
  EXPECT_FALSE(reg.refined);
  EXPECT_EQ(reg.back_to_palm.matrix(), reg.marker_only.matrix());
  bool warned = false;
  for (const auto& w : reg.warnings) warned = warned || w.find("refinement refused") != std::string::npos;
  EXPECT_TRUE(warned);
}

// ---------------------------------------------------------------- the whole stage

// The markers' small fits (register/small_fit.hpp) take Ceres's steps: the same parameters as
// Ceres's own Levenberg–Marquardt (its default options, one residual block per sample) after
// 1, 3 and 50 iterations, on a noisy cap seen from above — its centre by the depth error from
// a start 1.1 mm off, by the weighted distance (the coarse rounds) from 2 mm off, and its centre
// and radius both free within bounds.
TEST(SmallFit, TakesCeressStepsAndEndsWhereCeresEnds) {
  Rng rng(11);
  std::vector<Eigen::Vector3d> cap;
  const Eigen::Vector3d centre(1.3, -0.7, 2.0);
  const double r = 3.9, floor = 0.2;
  for (double x = -3.6; x <= 3.6; x += 0.2)
    for (double y = -3.6; y <= 3.6; y += 0.2) {
      const double h2 = r * r - x * x - y * y;
      if (h2 < 0.3 * r * r) continue;
      cap.emplace_back(centre.x() + x, centre.y() + y, centre.z() + std::sqrt(h2) + 0.05 * rng.normal());
    }
  ASSERT_GT(cap.size(), 300u);
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const auto ceres_fit = [&](std::vector<double> x, int iterations, const std::function<ceres::CostFunction*(const Eigen::Vector3d&)>& make,
                             bool free_radius) {
    ceres::Problem problem;
    for (const auto& p : cap) {
      if (free_radius) problem.AddResidualBlock(make(p), nullptr, x.data(), &x[3]);
      else problem.AddResidualBlock(make(p), nullptr, x.data());
    }
    if (free_radius) {
      problem.SetParameterLowerBound(&x[3], 0, 0.1 * r);
      problem.SetParameterUpperBound(&x[3], 0, 10.0 * r);
    }
    ceres::Solver::Options o;
    o.linear_solver_type = ceres::DENSE_QR;
    o.max_num_iterations = iterations;
    o.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(o, &problem, &summary);
    return x;
  };
  const Eigen::Vector3d near_start(0.9, -0.2, 1.1), far_start(2.5, 0.6, 3.0);
  for (int iterations : {1, 3, 50}) {  // every step the same, not only the end
    small_fit::Options so;
    so.max_iterations = iterations;
    // The depth error, the radius fixed.
    std::vector<double> x = {near_start.x(), near_start.y(), near_start.z()};
    std::vector<SphereResidual> depth;
    for (const auto& p : cap) depth.emplace_back(p, r, floor);
    const int made_x = small_fit::minimise<3>(x.data(), static_cast<int>(cap.size()), [&](int k, const auto* c, auto* e) { depth[k](c, e); },
                                              {-kInf, -kInf, -kInf}, {kInf, kInf, kInf}, so);
    const auto cx = ceres_fit({near_start.x(), near_start.y(), near_start.z()}, iterations,
                              [&](const Eigen::Vector3d& p) { return SphereResidual::Create(p, r, floor); }, false);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(x[k], cx[k], 1e-12) << "depth error: parameter " << k << " after " << iterations;
    // The weighted distance.
    std::vector<double> y = {far_start.x(), far_start.y(), far_start.z()};
    std::vector<SphereDistanceResidual> dist;
    for (const auto& p : cap) dist.emplace_back(p, r, SphereDistanceResidual::weight(p, far_start, r, floor));
    small_fit::minimise<3>(y.data(), static_cast<int>(cap.size()), [&](int k, const auto* c, auto* e) { dist[k](c, e); },
                           {-kInf, -kInf, -kInf}, {kInf, kInf, kInf}, so);
    const auto cy = ceres_fit({far_start.x(), far_start.y(), far_start.z()}, iterations,
                              [&](const Eigen::Vector3d& p) { return SphereDistanceResidual::Create(p, far_start, r, floor); }, false);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(y[k], cy[k], 1e-12) << "distance: parameter " << k << " after " << iterations;
    // Centre and radius free, the radius bounded.
    std::vector<double> z = {near_start.x(), near_start.y(), near_start.z(), 3.0};
    std::vector<FreeRadiusResidual> free;
    for (const auto& p : cap) free.emplace_back(p, floor);
    const int made_z = small_fit::minimise<4>(z.data(), static_cast<int>(cap.size()), [&](int k, const auto* c, auto* e) { free[k](c, c + 3, e); },
                                              {-kInf, -kInf, -kInf, 0.1 * r}, {kInf, kInf, kInf, 10.0 * r}, so);
    const auto cz = ceres_fit({near_start.x(), near_start.y(), near_start.z(), 3.0}, iterations,
                              [&](const Eigen::Vector3d& p) { return FreeRadiusResidual::Create(p, floor); }, true);
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(z[k], cz[k], 1e-12) << "free radius: parameter " << k << " after " << iterations;
    if (iterations == 50) {
      EXPECT_NEAR((Eigen::Vector3d(x[0], x[1], x[2]) - centre).norm(), 0.0, 0.02);
      EXPECT_NEAR((Eigen::Vector3d(z[0], z[1], z[2]) - centre).norm(), 0.0, 0.02);
      EXPECT_NEAR(z[3], r, 0.02);
      EXPECT_GE(made_x, 2);  // the fits moved: a comparison of two starts left as they were proves nothing
      EXPECT_GE(made_z, 2);
    }
  }
}

TEST(Register, FixtureAgainstTruth) {
  const RangeScan back = load_scan(kFixture + "back"), palm = load_scan(kFixture + "palm");
  const Registration reg = register_scans(back, palm, "back", "palm", RegistrationOptions{}, nullptr, kQuiet);
  const Json truth = load_json_object(kFixture + "truth.json");
  const Eigen::Isometry3d T = isometry_from_json(truth["back_to_palm"], "back_to_palm", "truth");
  const RegistrationError e = registration_error(reg.back_to_palm, T, default_hand().mesh.vertices);
  EXPECT_LT(e.rotation_deg, 0.02);
  EXPECT_LT(e.mean_mm, 0.05);
  EXPECT_LT(e.max_mm, 0.1);
  EXPECT_TRUE(reg.warnings.empty());
  EXPECT_EQ(reg.detail.match.pairs.size(), 9u);
  // Merged cloud: both sides, no sample near a marker.
  size_t sides[2] = {0, 0};
  for (const auto& p : *reg.merged) {
    ++sides[p.label];
    for (const auto& c : reg.markers_palm)
      ASSERT_GT((p.getVector3fMap().cast<double>() - c).norm(), 3.0);
  }
  EXPECT_GT(sides[kSidePalm], 50000u);
  EXPECT_GT(sides[kSideBack], 50000u);
  EXPECT_EQ(reg.markers_palm.size(), 9u);
}

TEST(Register, FixtureMarkerRadiusEstimatedWithinTheBounds) {
  // The radius from the scans (the default pipeline's way), within 3 standard deviations of
  // the estimate's error over the family's 48 pairs (0.0073 mm), and the registration within
  // the bounds. Measured 3.983 mm, 0.0021 deg, 0.031 mm: one draw of the estimate's
  // noise (the palm scan's nine caps lean 0.034 mm small on average, on these scans only:
  // docs/registration.md). It was 4.000 mm and 0.0088 mm with the geometric residual, whose
  // estimate leaned 0.006 mm small over the family and scattered 0.011 mm.
  const RangeScan back = load_scan(kFixture + "back"), palm = load_scan(kFixture + "palm");
  RegistrationOptions o;
  o.estimate_radius = true;
  const Registration reg = register_scans(back, palm, "back", "palm", o, nullptr, kQuiet);
  const Json truth = load_json_object(kFixture + "truth.json");
  const Eigen::Isometry3d T = isometry_from_json(truth["back_to_palm"], "back_to_palm", "truth");
  const RegistrationError e = registration_error(reg.back_to_palm, T, default_hand().mesh.vertices);
  std::printf("fixture, radius estimated: %.4f mm; registration %.4f deg, %.4f mm mean\n", reg.marker_radius_mm,
              e.rotation_deg, e.mean_mm);
  EXPECT_NEAR(reg.marker_radius_mm, 4.0, 0.022);
  EXPECT_LT(e.rotation_deg, 0.02);
  EXPECT_LT(e.mean_mm, 0.05);
  // Its own error estimate (measured 0.012 deg / 0.020 mm) is under the default warning
  // figures (0.02 deg / 0.05 mm); asked to warn above 0.005 deg it says what it holds.
  EXPECT_TRUE(reg.warnings.empty()) << reg.warnings.front();
  o.warn_rotation_sigma_deg = 0.005;
  const Registration strict = register_scans(back, palm, "back", "palm", o, nullptr, kQuiet);
  ASSERT_EQ(strict.warnings.size(), 1u);
  EXPECT_NE(strict.warnings[0].find("the scans hold this registration to 0.01"), std::string::npos)
      << strict.warnings[0];
  EXPECT_NE(strict.warnings[0].find("more or larger markers"), std::string::npos) << strict.warnings[0];
  EXPECT_EQ(registration_to_json(strict)["status"], "ok_with_warnings");
}

// The radius estimate leaves out the back-scan search of a candidate that cannot win (its
// palm bumps fewer than another candidate's matched markers). Safe only if such a candidate
// could not have won: the estimate with only the searched candidates must be the same bits,
// and each left-out one must be beaten by its palm count alone. Two pairs: the fixture, and a
// second hand with 3 mm markers (where other candidates are searched).
TEST(Register, RadiusCandidatesLeftOutCouldNotHaveWon) {
  ReplicaOptions ro;
  ro.marker_radius_mm = 3.0;
  const ScanPair second = synthesize_scan_pair(second_hand().mesh, second_hand().rig, ro, ScannerOptions{}, 203, false);
  const std::pair<RangeScan, RangeScan> pairs[] = {{load_scan(kFixture + "back"), load_scan(kFixture + "palm")},
                                                   {second.back.scan, second.palm.scan}};
  for (const auto& [back, palm] : pairs) {
    RegistrationOptions o;
    o.estimate_radius = true;
    o.refine_enabled = false;
    const Registration full = register_scans(back, palm, "back", "palm", o, nullptr, kQuiet);
    const MarkerRadiusDetail& d = full.detail.radius;
    ASSERT_EQ(d.tried.size(), o.radius_candidates_mm.size());
    size_t best = 0, left_out = 0;
    std::vector<double> searched;
    for (const RadiusTry& t : d.tried)
      if (t.back_searched) best = std::max(best, t.matched), searched.push_back(t.radius_mm);
    for (const RadiusTry& t : d.tried)
      if (!t.back_searched) {
        ++left_out;
        EXPECT_TRUE(t.palm < 3 || t.palm < best) << t.radius_mm << " mm: " << t.palm << " palm bumps, best " << best;
      }
    std::printf("candidates left out of the back scan: %zu of %zu; estimate %.5f mm\n", left_out, d.tried.size(),
                d.radius_mm);
    o.radius_candidates_mm = searched;
    const Registration only = register_scans(back, palm, "back", "palm", o, nullptr, kQuiet);
    EXPECT_EQ(only.detail.radius.candidate_mm, d.candidate_mm);
    EXPECT_EQ(only.marker_radius_mm, full.marker_radius_mm);
    EXPECT_EQ(only.back_to_palm.matrix(), full.back_to_palm.matrix());
  }
}

// The estimate over pairs of two hands with 3 mm markers: its error is what moves the back
// scan along the hand's normal (twice over), so it must be unbiased and tight, not only right
// on one pair. Each cap's free radius from its depth errors, off the skin it sits in, and one
// radius fitted to all caps (docs/registration.md).
TEST(Register, MarkerRadiusEstimateUnbiasedOverPairs) {
  ReplicaOptions ro;
  ro.marker_radius_mm = 3.0;
  RegistrationOptions opts;
  opts.estimate_radius = true;
  double sum = 0, sum2 = 0, worst = 0, radius_z2 = 0, rotation_ratio2 = 0, displacement_ratio2 = 0;
  int n = 0;
  for (const Hand* hand : {&default_hand(), &second_hand()})
    for (std::uint64_t seed = 201; seed <= 206; ++seed) {
      const Outcome o = register_pair(*hand, seed, ro, ScannerOptions{}, opts);
      const double err = o.reg.marker_radius_mm - ro.marker_radius_mm;
      const RegistrationUncertainty& u = o.reg.detail.uncertainty;
      ASSERT_TRUE(u.valid) << "seed " << seed;
      ASSERT_GT(u.radius_mm, 0) << "seed " << seed;
      const double sd_r = u.radius_mm, sd_rot = u.rotation_deg, sd_disp = u.displacement_mm;
      std::printf("hand %d seed %d: radius %+.4f mm off (its 1 sigma %.4f); registration %.4f deg (%.4f), %.4f mm mean (%.4f)\n",
                  hand == &default_hand() ? 1 : 2, static_cast<int>(seed), err, sd_r, o.chosen.rotation_deg, sd_rot,
                  o.chosen.mean_mm, sd_disp);
      // The warning is given exactly when the estimate exceeds its figures.
      bool warned = false;
      for (const auto& w : o.reg.warnings) warned = warned || w.find("the scans hold this registration") != std::string::npos;
      EXPECT_EQ(warned, sd_rot > opts.warn_rotation_sigma_deg || sd_disp > opts.warn_displacement_sigma_mm)
          << "seed " << seed;
      sum += err;
      sum2 += err * err;
      worst = std::max(worst, std::abs(err));
      radius_z2 += (err / sd_r) * (err / sd_r);
      rotation_ratio2 += (o.chosen.rotation_deg / sd_rot) * (o.chosen.rotation_deg / sd_rot);
      displacement_ratio2 += (o.chosen.mean_mm / sd_disp) * (o.chosen.mean_mm / sd_disp);
      ++n;
    }
  const double mean = sum / n, rms = std::sqrt(sum2 / n);
  std::printf("radius error over %d pairs: mean %+.4f, rms %.4f, worst %.4f mm\n", n, mean, rms, worst);
  EXPECT_LE(std::abs(mean), 0.005);
  EXPECT_LE(rms, 0.010);
  EXPECT_LE(worst, 0.022);
  // The registration's own error estimate (registration.json's `uncertainty`) is honest: the
  // errors against the truth, over the pairs, are of its size (RMS of error / estimate within
  // [0.5, 1.5]; measured here 0.93 (radius), 0.77 (rotation), 0.95 (displacement), on the
  // family's 48 pairs 0.96, 0.98, 0.93. The rotation's estimate read 0.55 here and 0.69 there
  // while it was taken in angle-axis coordinates, which near the turnover's 180° are not angles).
  const double rz = std::sqrt(radius_z2 / n), rr = std::sqrt(rotation_ratio2 / n), rd = std::sqrt(displacement_ratio2 / n);
  std::printf("error / own estimate, RMS over the pairs: radius %.2f, rotation %.2f, displacement %.2f\n", rz, rr, rd);
  for (double x : {rz, rr, rd}) {
    EXPECT_GE(x, 0.5);
    EXPECT_LE(x, 1.5);
  }
}

TEST(Register, ManualMarkersGiveTheSameResult) {
  const RangeScan back = load_scan(kFixture + "back"), palm = load_scan(kFixture + "palm");
  const Json truth = load_json_object(kFixture + "truth.json");
  Rng rng(3);
  Json hints = {{"format", "handskin-markers/1"}};
  for (const char* side : {"back", "palm"}) {
    Json a = Json::array();
    for (const auto& m : truth[std::string("markers_") + side]) {
      const Eigen::Vector3d c = to_vec3(m, "m", "t") + Eigen::Vector3d(rng.normal(), rng.normal(), rng.normal()) * 0.7;
      a.push_back({c.x(), c.y(), c.z()});
    }
    hints[side] = a;
  }
  const std::string dir = test::temp_dir("hints");
  save_json(dir + "/markers.json", hints);
  const MarkerHints h = load_marker_hints(dir + "/markers.json");
  const Registration manual = register_scans(back, palm, "back", "palm", RegistrationOptions{}, &h, kQuiet);
  const Registration automatic = register_scans(back, palm, "back", "palm", RegistrationOptions{}, nullptr, kQuiet);
  EXPECT_LT(rotation_difference_deg(manual.back_to_palm, automatic.back_to_palm), 1e-3);
  EXPECT_TRUE(manual.detail.back.manual_markers);

  // A position with no marker near it is an error naming the file and the entry.
  hints["palm"][4] = {10.0, 10.0, 10.0};
  save_json(dir + "/bad.json", hints);
  const MarkerHints bad = load_marker_hints(dir + "/bad.json");
  const std::string err =
      input_error_of([&] { register_scans(back, palm, "back", "palm", RegistrationOptions{}, &bad, kQuiet); });
  EXPECT_NE(err.find("bad.json"), std::string::npos) << err;
  EXPECT_NE(err.find("palm[4]"), std::string::npos) << err;
  // Every back position 50 mm off (another pair's, or another frame's): the radius's estimate
  // finds nothing at them, and the error names the file, not the scans (it told the user to
  // give approximate positions with --markers, which they had).
  for (auto& m : hints["back"]) m[0] = m[0].get<double>() + 50.0;
  hints["palm"][4] = truth["markers_palm"][4];
  save_json(dir + "/far.json", hints);
  const MarkerHints far = load_marker_hints(dir + "/far.json");
  RegistrationOptions estimated;  // as run and register do without markers.radius_mm
  estimated.estimate_radius = true;
  const std::string far_err = input_error_of([&] { register_scans(back, palm, "back", "palm", estimated, &far, kQuiet); });
  EXPECT_NE(far_err.find("far.json: at the positions it gives no radius finds 3 marker spheres"), std::string::npos) << far_err;
  EXPECT_NE(far_err.find("are they this pair's markers"), std::string::npos) << far_err;
}

TEST(Register, RefusesWhatItCannotTrust) {
  const RangeScan back = load_scan(kFixture + "back"), palm = load_scan(kFixture + "palm");
  // Markers of another radius than the replica's: none found.
  RegistrationOptions wrong_radius;
  wrong_radius.spheres.radius_mm = 6.0;
  std::string err = input_error_of([&] { register_scans(back, palm, "b.png", "p.png", wrong_radius, nullptr, kQuiet); });
  EXPECT_NE(err.find("b.png"), std::string::npos) << err;
  EXPECT_NE(err.find("need at least 3"), std::string::npos) << err;

  // Two different objects: the palm scan of another replica (other marker layout).
  ReplicaOptions ro;
  const ScanPair other = synthesize_scan_pair(second_hand().mesh, second_hand().rig, ro, ScannerOptions{}, 99, false);
  err = input_error_of([&] { register_scans(back, other.palm.scan, "b.png", "p.png", RegistrationOptions{}, nullptr, kQuiet); });
  EXPECT_NE(err.find("do not match"), std::string::npos) << err;

  // The same scan given as both sides is matched perfectly but is not a turnover; it is
  // still a valid rigid registration (identity), so it must come out as such, not garbage.
  const Registration same = register_scans(palm, palm, "p.png", "p.png", RegistrationOptions{}, nullptr, kQuiet);
  EXPECT_LT(rotation_difference_deg(same.back_to_palm, Eigen::Isometry3d::Identity()), 1e-6);
}

// Acceptance: 20 pairs, two hands, random seeds and placements, the bounds for every
// pair: rotation <= 0.02 deg, skin displacement mean <= 0.05 mm, max <= 0.1 mm. (With 3 mm
// markers rotation reaches 0.03 deg on some pairs: docs/registration.md.) The table printed
// here is the one in docs/registration.md.
TEST(Register, AcceptanceTwentyPairsTwoHands) {
  double worst_rot = 0, worst_mean = 0, worst_max = 0, sum_rot = 0, sum_rot_m = 0;
  int n = 0, refined_better = 0, rot_within = 0;
  std::printf("hand seed | rotation deg (marker-only) | skin mean mm (marker-only) | skin max mm (marker-only)\n");
  for (const Hand* hand : {&default_hand(), &second_hand()})
    for (std::uint64_t seed = 101; seed <= 110; ++seed) {
      const Outcome o = register_pair(*hand, seed, ReplicaOptions{}, ScannerOptions{});
      std::printf("%d %3d | %.4f (%.4f) | %.4f (%.4f) | %.4f (%.4f)\n", hand == &default_hand() ? 1 : 2,
                  static_cast<int>(seed), o.chosen.rotation_deg, o.marker_only.rotation_deg, o.chosen.mean_mm,
                  o.marker_only.mean_mm, o.chosen.max_mm, o.marker_only.max_mm);
      EXPECT_LE(o.chosen.rotation_deg, 0.02) << "seed " << seed;
      EXPECT_LE(o.chosen.mean_mm, 0.05) << "seed " << seed;
      EXPECT_LE(o.chosen.max_mm, 0.1) << "seed " << seed;
      EXPECT_TRUE(o.reg.warnings.empty()) << o.reg.warnings.front();
      EXPECT_TRUE(o.reg.refined);
      worst_rot = std::max(worst_rot, o.chosen.rotation_deg);
      worst_mean = std::max(worst_mean, o.chosen.mean_mm);
      worst_max = std::max(worst_max, o.chosen.max_mm);
      sum_rot += o.chosen.rotation_deg;
      sum_rot_m += o.marker_only.rotation_deg;
      refined_better += o.chosen.mean_mm <= o.marker_only.mean_mm;
      rot_within += o.chosen.rotation_deg <= 0.02;
      ++n;
    }
  std::printf("worst: rotation %.4f deg, skin mean %.4f mm, skin max %.4f mm; mean rotation %.4f deg "
              "(marker-only %.4f); rotation <= 0.02 deg in %d of %d; refined <= marker-only (skin mean) in %d of %d\n",
              worst_rot, worst_mean, worst_max, sum_rot / n, sum_rot_m / n, rot_within, n, refined_better, n);
  EXPECT_LE(sum_rot / n, 0.012);
  // Over the set the refinement is no worse than the marker-only fit.
  EXPECT_LE(sum_rot, sum_rot_m);
}

// One marker missing, one extra bump, noise doubled, longer laser shadows (markers half
// in shadow), and the first three at once: within twice the bounds, the missing /
// extra marker reported.
TEST(Register, HardCasesWithinTwiceTheBounds) {
  struct Case {
    const char* name;
    ReplicaOptions ro;
    ScannerOptions so;
    size_t warnings;
  };
  std::vector<Case> cases;
  {
    Case c{"one marker missing", {}, {}, 2};
    c.ro.omit_marker_in_back = 4;
    cases.push_back(c);
  }
  {
    Case c{"extra bump", {}, {}, 2};
    c.ro.extra_bump = true;
    cases.push_back(c);
  }
  {
    Case c{"noise doubled", {}, {}, 0};
    c.so.noise_sigma_mm = 0.1;
    cases.push_back(c);
  }
  {
    Case c{"long laser shadows (30 deg)", {}, {}, 0};  // markers half in shadow
    c.so.laser_tilt_deg = 30;
    cases.push_back(c);
  }
  {
    Case c{"all three at once", {}, {}, 2};
    c.ro.omit_marker_in_back = 2;
    c.ro.extra_bump = true;
    c.so.noise_sigma_mm = 0.1;
    cases.push_back(c);
  }
  for (const auto& c : cases)
    for (const Hand* hand : {&default_hand(), &second_hand()})
      for (std::uint64_t seed : {201, 202}) {
        const Outcome o = register_pair(*hand, seed, c.ro, c.so);
        std::printf("%-24s hand %d seed %d: rot %.4f deg, mean %.4f mm, max %.4f mm, %zu warnings\n", c.name,
                    hand == &default_hand() ? 1 : 2, static_cast<int>(seed), o.chosen.rotation_deg, o.chosen.mean_mm,
                    o.chosen.max_mm, o.reg.warnings.size());
        EXPECT_LE(o.chosen.rotation_deg, 0.04) << c.name << " seed " << seed;
        EXPECT_LE(o.chosen.mean_mm, 0.1) << c.name;
        EXPECT_LE(o.chosen.max_mm, 0.2) << c.name;
        // Missing / extra markers are reported (count warning + unmatched marker warning).
        EXPECT_GE(o.reg.warnings.size(), c.warnings) << c.name;
      }
}

TEST(Register, ABumpyObjectIsBoundedNotStuck) {
  // Twenty marker-sized bumps: matching keeps the strongest 15 per scan (its cost grows with
  // the sixth power of the count) and still registers the scan onto itself.
  ScannerOptions so;
  Scene scene;
  add_box(&scene, {40, 30, 0}, {210, 170, 25}, 0);
  Rng rng(8);
  for (int k = 0; k < 20; ++k) {
    const Eigen::Vector3d c(rng.uniform(50, 200), rng.uniform(40, 160), 25.0);
    add_sphere(&scene, c, 4.0, k + 1);
  }
  const ScanSimulation sim = simulate_scan(scene, so, ScanSide::Back, 3);
  RangeScan palm = sim.scan;
  palm.meta.side = ScanSide::Palm;
  const Registration reg = register_scans(sim.scan, palm, "b", "p", RegistrationOptions{}, nullptr, kQuiet);
  EXPECT_LT(rotation_difference_deg(reg.back_to_palm, Eigen::Isometry3d::Identity()), 1e-6);
  EXPECT_GT(reg.detail.back.candidates_dropped, 0u);
  EXPECT_EQ(reg.detail.back.markers.size(), 15u);
}
