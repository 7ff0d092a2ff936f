#include "skin/skin_mesh.hpp"

#include <cstdlib>

#include <CGAL/Polygon_mesh_processing/self_intersections.h>

#include <algorithm>
#include <atomic>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>

#include "core/atomic_file.hpp"
#include "core/dof.hpp"
#include "core/errors.hpp"
#include "mesh/from_cgal.hpp"
#include "skin/auto_rig.hpp"
#include "skin/profile.hpp"
#include "skin/skin_steps.hpp"

namespace handskin {

namespace {

using namespace skin_steps;
namespace PMP = CGAL::Polygon_mesh_processing;
using profile::segment_distance2;
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// A digit's links may lie this far from the middle of its sections' extent (the larger of
// the two): a rig that fits puts them within ~1 mm (the bones lie a little dorsal); 4 mm off
// already gives 3.5–4 mm (measured on the fixture, docs/skin.md).
constexpr double kMaxAxisOffsetMm = 2.5, kMaxAxisOffsetShare = 0.3;
constexpr double kUnseenWarnShare = 0.3;  // of the skin's vertices unseen: a warning
double allowed_axis_offset(const SkinTubeReport& r) { return std::max(kMaxAxisOffsetMm, kMaxAxisOffsetShare * r.section_radius_mm); }
// build_skin's refusal of a digit whose links lie beside its sections; empty when they do not.
// A given rig is held to every section as it shows the middle (axis_offset_seen_mm): a hand
// with its MCPs flexed 60 deg, whose fingers' backs neither scan sees, had its own true rig
// refused by the round sections' measure (its middle finger 7.0 mm off by the arcs' middles,
// its little finger 4.5 mm by the few round sections by the knuckle, which hold the palm).
std::string off_sections(const TubeBuild& t, bool rig_given = false) {
  const SkinTubeReport& r = t.report;
  const double off = rig_given ? r.axis_offset_seen_mm : r.axis_offset_mm;
  if (t.id == 0 || !r.present || r.section_radius_mm <= 0 || off <= allowed_axis_offset(r)) return {};
  char buf[240];
  std::snprintf(buf, sizeof buf,
                "the %s's links lie %.1f mm from the middle of its sections (allowed %.1f mm): the skeleton "
                "does not fit this scan",
                skin_tube_name(t.id), off, allowed_axis_offset(r));
  return buf;
}
// Steps 1-2 and the ring spacing, as build_skin makes them.
struct DigitFrame {
  HandFrame H;
  TubePoints P;
  double h = 0;
};
DigitFrame digit_frame(const std::vector<Eigen::Vector3d>& points, const Rig& rig, const SkinOptions& o) {
  DigitFrame d;
  d.H = to_hand_frame(points, rig, bones_from_rig(rig));
  d.P = assign_points(d.H, o.thumb_overlap_mm);
  const Eigen::Vector3d tip_mid = d.H.J[finger_chain(Finger::Middle).back()];
  d.h = std::max((tip_mid.x() - d.H.lo.x()) / o.slicing.planes, 0.5);  // ring spacing, mm
  return d;
}

}  // namespace

const char* skin_tube_name(int tube) {
  static const char* names[kSkinTubes] = {"palm", "thumb", "index", "middle", "ring", "little"};
  return tube >= 0 && tube < kSkinTubes ? names[tube] : "?";
}

bool SkinOptions::IsValid(std::string* error) const {
  if (!slicing.IsValid(error)) return false;
  if (smoothing_rings < 0 || smoothing_rings > 5) return invalid(error, "skin.smoothing_rings must be in [0, 5]");
  if (!(wrinkle_mm >= 0 && wrinkle_mm <= 10)) return invalid(error, "skin.wrinkle_mm must be in [0, 10]");
  if (max_triangles != 0 && (max_triangles < 1000 || max_triangles > 1000000))
    return invalid(error, "skin.max_triangles must be 0 (no decimation) or in [1000, 1000000]");
  if (!(decimation_tolerance_mm > 0 && decimation_tolerance_mm <= 1)) return invalid(error, "skin.decimation_tolerance_mm must be in (0, 1]");
  if (!(data_fit.max_move_mm > 0 && data_fit.max_move_mm <= 10)) return invalid(error, "skin.fit_max_move_mm must be in (0, 10]");
  if (!(data_fit.smoothness > 0 && data_fit.smoothness <= 100)) return invalid(error, "the data fit's smoothness must be in (0, 100]");
  if (data_fit.rounds < 1 || data_fit.rounds > 20) return invalid(error, "the data fit's rounds must be in [1, 20]");
  if (data_fit.max_points < 100 || data_fit.max_points > 10000000) return invalid(error, "the data fit's max_points must be in [100, 1e7]");
  if (!(fair_unseen.seen_mm > 0 && fair_unseen.seen_mm <= 10)) return invalid(error, "the fairing's seen_mm must be in (0, 10]");
  if (!(fair_unseen.crease_deg > 0 && fair_unseen.crease_deg < 180)) return invalid(error, "the fairing's crease_deg must be in (0, 180)");
  if (fair_unseen.rings < 0 || fair_unseen.rings > 50) return invalid(error, "the fairing's rings must be in [0, 50]");
  if (!(fair_unseen.cut_margin_mm >= 0 && fair_unseen.cut_margin_mm <= 50)) return invalid(error, "the fairing's cut_margin_mm must be in [0, 50]");
  if (!(fair_unseen.away_mm >= 0 && fair_unseen.away_mm <= 20)) return invalid(error, "the fairing's away_mm must be in [0, 20]");
  if (!(thumb_overlap_mm >= 0 && thumb_overlap_mm <= 20)) return invalid(error, "skin.thumb_overlap_mm must be in [0, 20]");
  if (cap_rings < 1 || cap_rings > 20) return invalid(error, "skin.cap_rings must be in [1, 20]");
  if (!(window_deg > 0 && window_deg <= 20)) return invalid(error, "skin.window_deg must be in (0, 20]");
  if (!(min_coverage_deg >= 90 && min_coverage_deg <= 360)) return invalid(error, "skin.min_coverage_deg must be in [90, 360]");
  return true;
}

bool SkinResult::watertight() const {
  return health.closed() && health.manifold() && health.components == 1 && health.volume_mm3 > 0 &&
         !(self_intersection_checked && self_intersects);
}

namespace {

// Steps 4.-5.: planes, slabs and rings: the palm, then each digit (kept apart from its
// neighbours, closed by its fingertip's dome); the tubes' reports and warnings, the check that
// the rig fits, and the regular ring grid before stitching (rig frame).
std::vector<TubeBuild> build_tubes(const HandFrame& H, const TubePoints& tube_points, const Webs& webs, double h,
                                   const SkinOptions& o, bool thumb_turns_slowly, SkinResult* R) {
  const int pps = o.slicing.points_per_segment;
  const Eigen::Isometry3d Ti = H.T.inverse();
  std::vector<TubeBuild> tubes(kSkinTubes);
  tubes[0] = palm_planes(H, tube_points, webs, h);
  resample_rings(&tubes[0], 8 * pps, o, false);
  for (int f = 0; f < kFingerCount; ++f) {
    TubeBuild& t = tubes[1 + f];
    t = digit_planes(H, tube_points, f, h, thumb_turns_slowly, o.rig_given);
    if (!t.report.present) continue;
    resample_rings(&t, 2 * pps, o, true);
    if (!t.report.present) continue;
    if (f >= 1) keep_apart(&t, H, f);
    add_dome(&t, 2 * pps, o.cap_rings, o);
  }
  for (auto& t : tubes) {
    t.report.name = skin_tube_name(t.id);
    if (!t.report.present && t.id != 0)
      R->warnings.push_back(std::string("no ") + skin_tube_name(t.id) +
                           (t.id == 1 ? "" : " finger") + " in the scan: the skin is built without it");
    R->tubes.push_back(t.report);
  }
  if (!tubes[0].report.present) throw InputError("merged cloud", "no palm section could be measured");
  R->wrist_cut = tubes[0].cut;
  // A rig that does not fit the cloud (another scan's, shifted, fingers swapped) puts a
  // digit's links beside the middle of its sections: refused rather than worked around.
  for (const auto& t : tubes)
    if (std::string why = off_sections(t, o.rig_given); !why.empty()) throw InputError("rig", why);
  // The regular ring grid, before stitching (rig frame).
  for (const auto& t : tubes) {
    RingGrid g;
    g.tube = t.id;
    g.present = t.report.present;
    for (size_t k = 0; k < t.rings.size(); ++k) {
      std::vector<Eigen::Vector3d> ring;
      for (const auto& p : t.rings[k]) ring.push_back(Ti * p);
      g.rings.push_back(std::move(ring));
      g.station.push_back(t.ring_station[k]);
    }
    if (t.pole) g.pole = Ti * *t.pole;
    R->grid.push_back(std::move(g));
  }
  return tubes;
}

// Each vertex's bone (the nearest link; a digit's vertex one of that digit's), tube and ring.
void label_vertices(const SM& skin, const SM::Property_map<SM::Vertex_index, std::pair<int, int>>& origin_of,
                    const HandFrame& H, SkinResult* R) {
  const auto& V = R->mesh.vertices;
  size_t vi = 0;
  for (auto v : skin.vertices()) {
    const auto [tube, ring] = origin_of[v];
    const Eigen::Vector3d ph = H.T * V[vi++];
    int best = 0;
    double bd = 1e300;
    for (size_t b = 0; b < H.A.size(); ++b) {
      if (tube > 0 && H.bone_tube[b] != tube) continue;  // a digit's vertex binds to that digit's links
      const double d = segment_distance2(ph, H.A[b], H.B[b]);
      if (d < bd) bd = d, best = static_cast<int>(b);
    }
    R->vertex_bone.push_back(best);
    R->vertex_tube.push_back(tube >= 0 ? tube : H.bone_tube[best]);
    R->vertex_ring.push_back(ring);
  }
}

}  // namespace

std::string rig_outside_cloud(const std::vector<Eigen::Vector3d>& points, const Rig& rig) {
  if (points.empty()) return "no points";
  try {
    to_hand_frame(points, rig, bones_from_rig(rig));
  } catch (const InputError& e) {
    return e.detail();
  }
  return {};
}

std::string digits_off_their_sections(const std::vector<Eigen::Vector3d>& points, const Rig& rig, const SkinOptions& o) {
  try {
    const DigitFrame d = digit_frame(points, rig, o);
    for (int f = 0; f < kFingerCount; ++f)
      if (std::string why = off_sections(digit_planes(d.H, d.P, f, d.h)); !why.empty()) return why;
  } catch (const InputError& e) {
    return e.detail();
  }
  return {};
}

std::optional<Rig> centre_digit_links(const std::vector<Eigen::Vector3d>& points, const Rig& rig, const SkinOptions& o,
                                      const std::vector<int>& also) {
  Rig r = rig;
  std::vector<int> chosen;  // the digits over the allowed offset at the start
  for (int round = 0; round < 3; ++round) {
    const DigitFrame d = digit_frame(points, r, o);
    const HandFrame& H = d.H;
    const Eigen::Isometry3d Ti = H.T.inverse();
    for (int f = 0; f < kFingerCount; ++f) {
      const TubeBuild t = digit_planes(H, d.P, f, d.h);
      if (!t.report.present || t.report.section_radius_mm <= 0) continue;
      if (round == 0 && (!off_sections(t).empty() || std::find(also.begin(), also.end(), f) != also.end()))
        chosen.push_back(f);
      if (std::find(chosen.begin(), chosen.end(), f) == chosen.end()) continue;
      std::vector<SectionMiddle> mids = section_middles(t, H, f);
      mids.erase(std::remove_if(mids.begin(), mids.end(), [](const SectionMiddle& m) { return !m.counted; }), mids.end());
      if (mids.empty()) continue;
      // The joints beyond the digit's root (the thumb's MCP, IP and tip; a finger's PIP, DIP
      // and tip: its MCP is the palm's, and stays) such that the links pass through their
      // sections' middles, each section's residual taken in its own plane (along the links
      // the sections say nothing), each joint held to where it is by kHold: a linear least
      // squares of 3 unknowns a joint. A finger's bones go kDigitBoneDorsalMm dorsal of the
      // middles, as the placement puts them; the thumb's stay on them, since a turned thumb's
      // nail faces aside (lifted toward the hand's back, one WebXR pair's skin went 0.099 ->
      // 0.125 mm from the truth). Sections much wider than the digit's usual hold the palm (a
      // flexed finger's first slabs lie within the palm's thickness) and are left out.
      constexpr double kHold = 0.3;
      const auto chain = finger_chain(static_cast<Finger>(f));
      const size_t axis_from = f == 0 ? 0 : 1, first = f == 0 ? 1 : 2, nj = chain.size() - first;
      const double lift = f == 0 ? 0.0 : kDigitBoneDorsalMm;
      std::vector<double> widths;
      for (const auto& m : mids) widths.push_back(m.ext.maxCoeff());
      std::nth_element(widths.begin(), widths.begin() + widths.size() / 2, widths.end());
      const double wide = 1.3 * widths[widths.size() / 2];
      std::vector<double> sj(chain.size(), 0.0);  // each joint's arc length along the links
      for (size_t k = axis_from + 1; k < chain.size(); ++k) sj[k] = sj[k - 1] + (H.J[chain[k]] - H.J[chain[k - 1]]).norm();
      Eigen::MatrixXd A = kHold * Eigen::MatrixXd::Identity(3 * nj, 3 * nj);
      Eigen::VectorXd b(3 * nj);
      for (size_t j = 0; j < nj; ++j) b.segment<3>(3 * j) = kHold * H.J[chain[first + j]];
      for (const auto& m : mids) {
        if (m.ext.maxCoeff() > wide) continue;
        size_t k = axis_from + 1;
        while (k + 1 < chain.size() && m.s > sj[k]) ++k;
        if (k < first || m.s < sj[k - 1] || m.s > sj[k]) continue;
        const double wb = (m.s - sj[k - 1]) / std::max(sj[k] - sj[k - 1], 1e-9), wa = 1 - wb;
        const Station& st = t.st[m.station];
        const Eigen::Matrix3d Pi = st.u * st.u.transpose() + st.v * st.v.transpose();
        Eigen::Vector3d c = st.o + m.mid.x() * st.u + (m.mid.y() + lift) * st.v;
        const size_t jb = k - first;
        if (k - 1 < first) {  // the link from the fixed root
          c -= wa * H.J[chain[k - 1]];
        } else {
          const size_t ja = jb - 1;
          A.block<3, 3>(3 * ja, 3 * ja) += wa * wa * Pi;
          A.block<3, 3>(3 * ja, 3 * jb) += wa * wb * Pi, A.block<3, 3>(3 * jb, 3 * ja) += wa * wb * Pi;
          b.segment<3>(3 * ja) += wa * Pi * c;
        }
        A.block<3, 3>(3 * jb, 3 * jb) += wb * wb * Pi;
        b.segment<3>(3 * jb) += wb * Pi * c;
      }
      const Eigen::VectorXd x = A.ldlt().solve(b);
      for (size_t j = 0; j < nj; ++j) r.joints[chain[first + j]] = Ti * Eigen::Vector3d(x.segment<3>(3 * j));
    }
    if (chosen.empty()) return std::nullopt;
  }
  return r;
}

SkinResult build_skin(const std::vector<Eigen::Vector3d>& points, const Rig& rig, const SkinOptions& o,
                      const std::function<void(const std::string&)>& progress, const std::function<void()>& beside,
                      const std::function<void()>& accepted) {
  // Fault injection (the header): this call's ordinal, taken before anything can throw.
  static std::atomic<int> builds{0};
  const int build_no = ++builds;
  bool fault_fold = false;
  if (const char* f = std::getenv("HANDSKIN_FAULT");
      f && (std::string(f) == "fold:" + std::to_string(build_no) || std::string(f) == "fold:all"))
    fault_fold = true;
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
  HandFrame H;
  std::vector<TubeBuild> tubes;
  PositionOrigin origin;  // exact position → tube, ring
  SM skin;
  // Steps 1-6 (the points to their tubes, the webs, the rings, the tubes' union) gain little
  // from a second thread (~125 ms on one, ~120 on two on the fixture): with work `beside`,
  // they run on one thread and it on the other.
  auto first_steps = [&] {
    // 1. the hand frame (the rig must sit in the cloud); 2. each point to its tube
    DigitFrame d = digit_frame(points, rig, o);
    H = std::move(d.H);
    const TubePoints& tube_points = d.P;
    const double h = d.h;
    // 3. the webs and the palm's end plane
    Webs webs = find_webs(H, h);
    R.webs = webs.points;
    for (auto& w : webs.warnings) R.warnings.push_back(std::move(w));
    if (webs.x_end - H.lo.x() < 5 * h)
      throw InputError("rig", "the finger webs lie at the wrist end of the cloud; the rig does not fit it");
    // 4.-5. planes, slabs and rings (build_tubes)
    const size_t warnings = R.warnings.size();
    tubes = build_tubes(H, tube_points, webs, h, o, false, &R);
    R.seconds_rings = since(t0);
    say("rings resampled (" + std::to_string(static_cast<int>(R.seconds_rings * 1000)) + " ms)");
    if (accepted) accepted();  // the rig's links lie on their sections (build_tubes' check)
    // 6. the tubes' meshes united into one surface
    const auto t1 = Clock::now();
    try {
      skin = stitch_tubes(tubes, H.T.inverse(), &origin, &R.pockets_removed, o.rig_given, fault_fold);
    } catch (const TubeFoldsError& e) {
      // The thumb's planes turn at once through its joints (a finger's over two tip radii):
      // its wide root turning slowly cost a raised thumb 0.3 % within 1 mm, and turned so
      // from its MCP on, the WebXR hand's bent thumb's patches kinked (docs/skin.md). A thumb
      // whose IP is bent 45 deg then folded its tube on its own true rig: the tubes are made
      // again with the thumb's planes turning slowly from its MCP on.
      if (e.tube != static_cast<int>(SkinTube::Thumb)) throw;
      say("the thumb's tube folds where its planes turn at once: its planes turned over its bends");
      R.warnings.resize(warnings), R.tubes.clear(), R.grid.clear(), origin.clear();
      tubes = build_tubes(H, tube_points, webs, h, o, true, &R);
      skin = stitch_tubes(tubes, H.T.inverse(), &origin, &R.pockets_removed, o.rig_given);
      R.thumb_turns_slowly = true;
    }
    R.seconds_union = since(t1);
    say("tubes stitched (" + std::to_string(static_cast<int>(R.seconds_union * 1000)) + " ms)");
  };
  if (!beside) {
    first_steps();
  } else {
    // An exception must not leave a section: the steps', else the caller's, is rethrown after
    // both.
    std::exception_ptr failed[2];
#pragma omp parallel sections
    {
#pragma omp section
      try {
        first_steps();
      } catch (...) {
        failed[0] = std::current_exception();
      }
#pragma omp section
      try {
        beside();
      } catch (...) {
        failed[1] = std::current_exception();
      }
    }
    for (const auto& e : failed)
      if (e) std::rethrow_exception(e);
  }
  const Eigen::Isometry3d Ti = H.T.inverse();

  // 7. decimation to the triangle budget (CGAL edge collapse, Garland–Heckbert plane
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
  R.seconds_decimation = since(t2);

  // 8. the skin fitted to the data: the rings' chords, the webs' saddles and the seams between
  // tubes lie up to a few millimetres off the scanned surface; each vertex moves onto it along
  // its normal where the cloud measures it (fit_data.cpp).
  const auto tf = Clock::now();
  std::vector<K::Point_3> before(skin.num_vertices());
  for (const auto v : skin.vertices()) before[v.idx()] = skin.point(v);
  R.data_fit = fit_to_data(&skin, points, o.data_fit);
  // 9. the unseen creases made fair (fair_unseen.cpp), then the moves of both steps that make
  // the skin cross itself taken back.
  {
    const Eigen::Vector3d cut_n = Ti.linear() * R.wrist_cut.n;
    const double cut_d = R.wrist_cut.d + cut_n.dot(Ti.translation());
    Moves faired;
    R.fair_unseen = fair_unseen(&skin, points, cut_n, cut_d, o.fair_unseen, &faired);
    if (o.check_self_intersections || o.data_fit.enabled || o.fair_unseen.enabled) {
      const Crossings c = take_back_crossings(&skin, before);  // also rounds to the written floats
      R.data_fit.reverted = c.reverted;
      R.data_fit.self_intersects = c.self_intersects;
    } else {
      round_as_written(&skin);
    }
    settle_fair_figures(skin, faired, &before, &R.fair_unseen);
    // Crossings left after the take-back are the union's (skin_steps.hpp, mend_crossings).
    if (R.data_fit.self_intersects) {
      R.crossings_mended = mend_crossings(&skin);
      if (R.crossings_mended > 0) {
        R.data_fit.self_intersects = false;
        R.warnings.push_back("the tubes' union crossed itself at " + std::to_string(R.crossings_mended) +
                             " pairs of triangles (slivers where a digit's tube meets the palm's); CGAL's repair "
                             "removed them and filled the hole");
      }
    }
    // Most skins have 16-21 % of their vertices unseen (the webs' flanks, the fingers' sides
    // between the two views); a hand posed so that the scans miss whole sides of its digits (its
    // MCPs flexed 60 deg: 37 %, its skin 93 % within 1 mm of the truth) is told so.
    const FairUnseen& f = R.fair_unseen;
    if (f.vertices > 0 && f.unseen >= kUnseenWarnShare * static_cast<double>(f.vertices)) {
      char buf[260];
      std::snprintf(buf, sizeof buf,
                    "%.0f %% of the skin's vertices have no scan point within %.1f mm: the skin there is the rings' "
                    "and the fairing's guess (scans that see more of the hand, its digits' backs and sides, give a "
                    "truer skin)",
                    100.0 * static_cast<double>(f.unseen) / static_cast<double>(f.vertices), o.fair_unseen.seen_mm);
      R.warnings.push_back(buf);
    }
  }
  R.mesh = to_mesh(skin);  // vertices in the order of skin.vertices()
  R.seconds_fit = since(tf);

  // --- checks, labels ---
  const auto t3 = Clock::now();
  if (o.check_self_intersections) {
    // The take-back after steps 8 and 9 ends with the test, on the positions as written.
    R.self_intersects = R.data_fit.self_intersects;
    R.self_intersection_checked = true;
  }
  R.health = mesh_health(R.mesh);
  R.seconds_checks = since(t3);
  label_vertices(skin, origin_of, H, &R);
  return R;
}

void save_skin_ply(const std::string& path, const SkinResult& skin) {
  auto V = skin.mesh.vertices;
  // Fault injection for tests (docs/architecture.md): HANDSKIN_FAULT=cross:1 writes the skin
  // with its first vertex pushed through the hand to the far side, so that its triangles
  // cross the skin: the report's checks of the written file must say so.
  if (const char* f = std::getenv("HANDSKIN_FAULT"); f && std::string(f) == "cross:1" && !V.empty()) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const auto& p : V) c += p;
    c /= static_cast<double>(V.size());
    V[0] = 2 * c - V[0];
  }
  const auto& F = skin.mesh.faces;
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
