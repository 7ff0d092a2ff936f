// The default hand (implicit surface meshed by CGAL) and the replica's scan pair.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>
#include <utility>

#include "core/atomic_file.hpp"
#include "core/dof.hpp"
#include "core/errors.hpp"
#include "core/json_util.hpp"
#include "core/transform.hpp"
#include "synth/hand_mesher.hpp"
#include "synth/hand_model.hpp"
#include "synth/cloud_sim.hpp"
#include "synth/replica.hpp"
#include "test_util.hpp"

using namespace handskin;

namespace {

struct DefaultHand {
  HandModel model;
  HandMeshResult mesh;
};
const DefaultHand& default_hand() {
  static const DefaultHand h = [] {
    DefaultHand d{build_hand_model(HandShapeOptions{}), {}};
    d.mesh = mesh_hand(d.model, HandMeshOptions{});
    return d;
  }();
  return h;
}

Eigen::Vector3d J(const Rig& rig, const char* name) { return rig.joints[joint_index(name).value()]; }

}  // namespace

TEST(DefaultHand, ClosedManifoldOutwardAndSized) {
  const auto& h = default_hand();
  const MeshHealth& m = h.mesh.health;
  EXPECT_TRUE(m.closed());
  EXPECT_TRUE(m.manifold());
  EXPECT_EQ(m.components, 1u);
  EXPECT_FALSE(h.mesh.self_intersects);
  EXPECT_GT(m.volume_mm3, 0);  // outward orientation
  EXPECT_GE(m.faces, 20000u);
  EXPECT_LE(m.faces, 60000u);
  // Euler characteristic of a sphere-like surface: V - E + F = 2.
  std::set<std::pair<int, int>> edges;
  for (const auto& f : h.mesh.mesh.faces)
    for (int k = 0; k < 3; ++k) edges.insert(std::minmax(f[k], f[(k + 1) % 3]));
  EXPECT_EQ(static_cast<long>(m.vertices) - static_cast<long>(edges.size()) + static_cast<long>(m.faces), 2);
  // Adult proportions: volume of a hand (without forearm) is a few hundred ml.
  EXPECT_GT(m.volume_mm3, 250e3);
  EXPECT_LT(m.volume_mm3, 650e3);
}

TEST(DefaultHand, JointsLieInsideTheSurface) {
  const auto& h = default_hand();
  for (int i = 0; i < kJointCount; ++i) {
    const Eigen::Vector3d& p = h.model.rig.joints[i];
    EXPECT_LT(h.model.value(p), -0.5) << joints()[i].name;
    EXPECT_NEAR(test::winding_number(h.mesh.mesh, p), 1.0, 1e-3) << joints()[i].name << " not inside the mesh";
  }
  // A point beyond the fingertip is outside.
  const Eigen::Vector3d tip = J(h.model.rig, "middle-finger-tip");
  EXPECT_NEAR(test::winding_number(h.mesh.mesh, tip + Eigen::Vector3d(5, 0, 0)), 0.0, 1e-3);
}

TEST(DefaultHand, AnatomicalMeasures) {
  const auto& h = default_hand();
  const Rig& rig = h.model.rig;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  double palm_lo = 1e9, palm_hi = -1e9, breadth_lo = 1e9, breadth_hi = -1e9;
  const double x_mcp = J(rig, "middle-finger-phalanx-proximal").x() - 15;  // across the metacarpal heads
  for (const Eigen::Vector3d& p : h.mesh.mesh.vertices) {
    lo = lo.cwiseMin(Eigen::Vector3d(p[0], p[1], p[2]));
    hi = hi.cwiseMax(Eigen::Vector3d(p[0], p[1], p[2]));
    // Across the metacarpal heads, leaving out the thumb beside them.
    if (std::abs(p[0] - x_mcp) < 1.0 && p[1] < J(rig, "index-finger-phalanx-proximal").y() + 15) {
      breadth_lo = std::min(breadth_lo, p[1]);
      breadth_hi = std::max(breadth_hi, p[1]);
      if (std::abs(p[1]) < 5) palm_lo = std::min(palm_lo, p[2]), palm_hi = std::max(palm_hi, p[2]);
    }
  }
  // Hand length: wrist joint to the middle fingertip's skin.
  std::printf("hand length %.1f mm, breadth %.1f mm, palm thickness %.1f mm\n", hi.x(), breadth_hi - breadth_lo,
              palm_hi - palm_lo);
  EXPECT_NEAR(hi.x(), HandShapeOptions{}.hand_length_mm, 3.0);
  EXPECT_NEAR(breadth_hi - breadth_lo, 85.0, 12.0);  // hand breadth at the metacarpals
  EXPECT_NEAR(palm_hi - palm_lo, 28.0, 6.0);         // palm thickness
  // Right hand: the thumb is on +Y, the little finger on -Y.
  EXPECT_GT(J(rig, "thumb-tip").y(), 30);
  EXPECT_LT(J(rig, "pinky-finger-tip").y(), -20);
  EXPECT_GT(J(rig, "middle-finger-tip").x(), J(rig, "index-finger-tip").x());
}

TEST(DefaultHand, OptionsMakeDifferentHands) {
  HandShapeOptions a, b;
  a.hand_length_mm = 170;
  b.hand_length_mm = 200;
  b.finger_spread_deg = 10;
  const HandModel ma = build_hand_model(a), mb = build_hand_model(b);
  const double la = J(ma.rig, "middle-finger-tip").norm(), lb = J(mb.rig, "middle-finger-tip").norm();
  EXPECT_NEAR(lb / la, 200.0 / 170.0, 0.01);
  const auto spread = [](const Rig& r) {
    return (J(r, "index-finger-tip") - J(r, "pinky-finger-tip")).norm();
  };
  EXPECT_GT(spread(mb.rig) / spread(ma.rig), 200.0 / 170.0 + 0.05);
  HandShapeOptions bad;
  bad.thickness_scale = 3;
  EXPECT_THROW(build_hand_model(bad), InputError);
}

// CGAL's surface mesher orders its work queue by cell addresses, so a mesh is reproducible
// for the same run of a fresh process (how the CLI and the fixture script use it), not for
// two calls within one process. The test therefore checks what users get: the command.
TEST(DefaultHand, SynthHandCommandIsDeterministic) {
  const std::string dir = test::temp_dir("det");
  std::string out;
  for (const char* d : {"/a", "/b"}) {
    ASSERT_EQ(test::run(std::string(HANDSKIN_BINARY) + " -q synth hand --hand-length 175 --facet-size 3 --no-render --out " + dir + d, &out), 0) << out;
  }
  EXPECT_EQ(read_file(dir + "/a/hand.ply"), read_file(dir + "/b/hand.ply"));
  EXPECT_EQ(read_file(dir + "/a/hand_rig.json"), read_file(dir + "/b/hand_rig.json"));
}

TEST(ScanPair, TruthIsConsistentWithTheScans) {
  const auto& h = default_hand();
  ReplicaOptions ro;
  ScannerOptions so;
  const ScanPair pair = synthesize_scan_pair(h.mesh.mesh, h.model.rig, ro, so, 42, false);
  ASSERT_EQ(pair.markers_hand.size(), 9u);
  // The turnover is a proper rotation of about 180° about a horizontal axis.
  EXPECT_NEAR(pair.back_to_palm.linear().determinant(), 1.0, 1e-9);
  const Eigen::Vector3d up_back_in_palm = pair.back_to_palm.linear() * Eigen::Vector3d::UnitZ();
  EXPECT_LT(up_back_in_palm.z(), -0.99);
  // Each marker visible in both scans.
  for (size_t k = 0; k < 9; ++k) {
    EXPECT_GE(pair.back.returns_per_object[k + 1], static_cast<size_t>(ro.min_marker_returns));
    EXPECT_GE(pair.palm.returns_per_object[k + 1], static_cast<size_t>(ro.min_marker_returns));
  }
  // Marker samples of both scans, taken to the palm frame, lie on the true spheres there.
  for (const ScanSimulation* sim : {&pair.back, &pair.palm}) {
    const Eigen::Isometry3d T = sim == &pair.back ? pair.back_to_palm : Eigen::Isometry3d::Identity();
    double worst = 0;
    for (int i = 0; i < so.scanlines; ++i)
      for (int j = 0; j < so.points; ++j) {
        const int ob = sim->pixel_object[static_cast<size_t>(i) * so.points + j];
        if (ob < 1) continue;
        const Eigen::Vector3d p_palm = T * sim->scan.position(i, j);
        const Eigen::Vector3d c_palm = pair.T_palm_hand * pair.markers_hand[ob - 1];
        worst = std::max(worst, std::abs((p_palm - c_palm).norm() - ro.marker_radius_mm));
      }
    EXPECT_LT(worst, 0.45);  // quantisation 0.1 + 4 sigma noise + sampling slant
  }
  // The rig in the palm frame is the hand rig moved by the palm placement.
  const Eigen::Isometry3d T_hand_rig = hand_frame_from_rig(h.model.rig);
  for (int i = 0; i < kJointCount; ++i)
    EXPECT_LT((pair.rig_palm.joints[i] - pair.T_palm_hand * (T_hand_rig * h.model.rig.joints[i])).norm(), 1e-9);
  EXPECT_EQ(pair.rig_palm.frame, "palm");
  // The marker pattern has no symmetry: every marker has its own distance signature.
  std::vector<std::vector<double>> sig(9);
  for (size_t a = 0; a < 9; ++a) {
    for (size_t b = 0; b < 9; ++b)
      if (a != b) sig[a].push_back((pair.markers_hand[a] - pair.markers_hand[b]).norm());
    std::sort(sig[a].begin(), sig[a].end());
  }
  for (size_t a = 0; a < 9; ++a)
    for (size_t b = a + 1; b < 9; ++b) {
      double d = 0;
      for (size_t k = 0; k < 8; ++k) d = std::max(d, std::abs(sig[a][k] - sig[b][k]));
      EXPECT_GE(d, ro.min_signature_gap_mm);
    }
}

// A hand model whose forearm ends rounded (not a sawn cast) is sawn flat as asked: the true
// skin is the sawn one, closed, one piece, outward, its proximal end the saw's plane.
TEST(ScanPair, SawnReplicaEndsFlatWhereAsked) {
  const auto& h = default_hand();
  ReplicaOptions ro;
  ro.saw_mm = 4.0;
  const ScanPair pair = synthesize_scan_pair(h.mesh.mesh, h.model.rig, ro, ScannerOptions{}, 7, false);
  const MeshHealth health = mesh_health(pair.skin_palm);
  EXPECT_TRUE(health.closed());
  EXPECT_TRUE(health.manifold());
  EXPECT_EQ(health.components, 1u);
  EXPECT_GT(health.volume_mm3, 0);
  EXPECT_LT(health.volume_mm3, mesh_health(h.mesh.mesh).volume_mm3);
  // In the hand frame (origin at the wrist joint, X along the hand) nothing lies proximal of
  // the cut, and the cut face holds vertices.
  double lowest = 1e300;
  size_t on_face = 0;
  for (const Eigen::Vector3d& p : pair.skin_palm.vertices) {
    const double x = (pair.T_palm_hand.inverse() * p).x();
    lowest = std::min(lowest, x);
    on_face += std::abs(x + 4.0) < 1e-6;
  }
  EXPECT_NEAR(lowest, -4.0, 1e-6);
  EXPECT_GT(on_face, 20u);
  ASSERT_EQ(pair.markers_hand.size(), 9u);
  // Sawing beyond the mesh's end leaves it as it is; an out-of-range saw is refused.
  ro.saw_mm = 90.0;
  EXPECT_EQ(mesh_health(synthesize_scan_pair(h.mesh.mesh, h.model.rig, ro, ScannerOptions{}, 7, false).skin_palm).faces,
            mesh_health(h.mesh.mesh).faces);
  ro.saw_mm = -1.0;
  EXPECT_THROW(synthesize_scan_pair(h.mesh.mesh, h.model.rig, ro, ScannerOptions{}, 7, false), InputError);
}

// A hand mesh whose faces face inward (another tool's winding) is the same solid: its scans,
// markers and true skin are the outward mesh's, bit for bit (it was refused as a hand whose
// markers could not be placed).
TEST(ScanPair, AMeshFacingInwardIsScannedAsTheSameSolid) {
  const auto& h = default_hand();
  Mesh inward = h.mesh.mesh;
  for (auto& f : inward.faces) std::reverse(f.begin(), f.end());
  ASSERT_LT(mesh_health(inward).volume_mm3, 0);
  const ScanPair a = synthesize_scan_pair(h.mesh.mesh, h.model.rig, ReplicaOptions{}, ScannerOptions{}, 7, false);
  const ScanPair b = synthesize_scan_pair(inward, h.model.rig, ReplicaOptions{}, ScannerOptions{}, 7, false);
  EXPECT_EQ(a.back.scan.values, b.back.scan.values);
  EXPECT_EQ(a.palm.scan.values, b.palm.scan.values);
  ASSERT_EQ(a.markers_hand.size(), b.markers_hand.size());
  for (size_t k = 0; k < a.markers_hand.size(); ++k) EXPECT_EQ(a.markers_hand[k], b.markers_hand[k]);
  EXPECT_EQ(a.skin_palm.faces, b.skin_palm.faces);
  EXPECT_GT(mesh_health(b.skin_palm).volume_mm3, 0);
}

TEST(ScanPair, FixtureTruthFile) {
  const std::string dir = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";
  const Json t = load_json_object(dir + "truth.json");
  const Eigen::Isometry3d T = isometry_from_json(t["back_to_palm"], "back_to_palm", "truth.json");
  const Eigen::Isometry3d Tp = isometry_from_json(t["palm_from_hand"], "palm_from_hand", "truth.json");
  const Eigen::Isometry3d Tb = isometry_from_json(t["back_from_hand"], "back_from_hand", "truth.json");
  EXPECT_LT((T.matrix() - (Tp * Tb.inverse()).matrix()).norm(), 1e-9);
  EXPECT_EQ(t["markers_palm"].size(), 9u);
  const Mesh skin = load_mesh(dir + "truth_skin.ply");
  EXPECT_TRUE(mesh_health(skin).closed());
}

namespace handskin {
namespace {
// A mesh and a rig a scanner may not take: in metres (refused with the unit named), or the rig
// of another frame (before: synth cloud wrote a cloud with a rig beside it, exit 0; synth scan
// said it could not place the markers).
TEST(ScanPair, AMeshAndRigInMetresInTwoFramesOrOpenAreRefused) {
  const std::string dir = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";
  const Mesh skin = load_mesh(dir + "truth_skin.ply");
  const Rig rig = load_rig(dir + "rig.json");
  EXPECT_NO_THROW(check_hand_and_rig(skin, rig));
  Mesh metres = skin;
  for (auto& v : metres.vertices) v *= 1e-3;
  Rig rig_m = rig;
  for (auto& j : rig_m.joints) j *= 1e-3;
  const std::string m = test::input_error_of([&] { simulate_cloud(metres, rig_m, CloudSimOptions{}, 1); });
  EXPECT_NE(m.find("--rig: its wrist lies 0.1"), std::string::npos) << m;
  EXPECT_NE(m.find("in metres?"), std::string::npos) << m;
  Rig shifted = rig;
  for (auto& j : shifted.joints) j.x() += 100;
  const std::string f = test::input_error_of([&] { simulate_cloud(skin, shifted, CloudSimOptions{}, 1); });
  EXPECT_NE(f.find("not in one frame or one unit"), std::string::npos) << f;
  EXPECT_NE(test::input_error_of([&] { synthesize_scan_pair(skin, shifted, ReplicaOptions{}, ScannerOptions{}, 1, false); })
                .find("not in one frame"),
            std::string::npos);
  // An open mesh (its wrist end cut away) is no cast: refused naming it (before: "cannot place
  // the markers ... with an irregular pattern").
  Mesh open = skin;
  const Eigen::Vector3d w = rig.joints[0], axis = (rig.joints[joint_index("middle-finger-tip").value()] - w).normalized();
  open.faces.clear();
  for (const auto& f : skin.faces)
    if ((skin.vertices[f[0]] - w).dot(axis) > -8) open.faces.push_back(f);
  ASSERT_LT(open.faces.size(), skin.faces.size());
  const std::string o = test::input_error_of([&] { synthesize_scan_pair(open, rig, ReplicaOptions{}, ScannerOptions{}, 1, false); });
  EXPECT_NE(o.find("--mesh: not a closed surface"), std::string::npos) << o;
}
}  // namespace
}  // namespace handskin
