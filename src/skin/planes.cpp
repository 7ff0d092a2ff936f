#include "skin/skin_steps.hpp"

#include <algorithm>
#include <cmath>


namespace handskin::skin_steps {

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

WristCut fit_wrist_cut(const std::vector<Eigen::Vector3d>& palm_pts, double x0, double band_mm) {
  WristCut cut;
  cut.d = x0;
  std::vector<const Eigen::Vector3d*> band;
  Eigen::Vector2d mn(1e300, 1e300), mx(-1e300, -1e300);
  for (const auto& p : palm_pts)
    if (p.x() < x0 + band_mm) {
      band.push_back(&p);
      mn = mn.cwiseMin(p.tail<2>());
      mx = mx.cwiseMax(p.tail<2>());
    }
  if (band.size() < 50) return cut;
  const Eigen::Vector2d c = 0.5 * (mn + mx);
  constexpr int kBins = 72;
  std::vector<const Eigen::Vector3d*> rim(kBins, nullptr);
  for (const Eigen::Vector3d* p : band) {
    const double a = std::atan2(p->z() - c.y(), p->y() - c.x());
    const int b = std::clamp(static_cast<int>((a + M_PI) / (2 * M_PI) * kBins), 0, kBins - 1);
    if (!rim[b] || p->x() < rim[b]->x()) rim[b] = p;
  }
  std::vector<Eigen::Vector3d> r;
  for (const auto* p : rim)
    if (p) r.push_back(*p);
  cut.rim_points = static_cast<int>(r.size());
  // x = a + b y + c z, least squares, trimmed twice at 3 robust sigmas (a bin whose nearest
  // point lies on the flank above the rim, where the scanners saw nothing lower).
  std::vector<char> keep(r.size(), 1);
  Eigen::Vector3d abc(x0, 0, 0);
  for (int round = 0; round < 3; ++round) {
    Eigen::MatrixXd A(r.size(), 3);
    Eigen::VectorXd y(r.size());
    int n = 0;
    double ylo = 1e300, yhi = -1e300;
    for (size_t i = 0; i < r.size(); ++i) {
      if (!keep[i]) continue;
      A.row(n) << 1, r[i].y(), r[i].z();
      y(n++) = r[i].x();
      ylo = std::min(ylo, r[i].y()), yhi = std::max(yhi, r[i].y());
    }
    if (n < 16 || yhi - ylo < 20) return cut;
    abc = A.topRows(n).colPivHouseholderQr().solve(y.head(n));
    std::vector<double> res;
    for (size_t i = 0; i < r.size(); ++i) res.push_back(std::abs(r[i].x() - abc.dot(Eigen::Vector3d(1, r[i].y(), r[i].z()))));
    std::vector<double> sorted = res;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double sigma = std::max(1.4826 * sorted[sorted.size() / 2], 0.1);
    double ss = 0;
    int kept = 0;
    for (size_t i = 0; i < r.size(); ++i) {
      keep[i] = res[i] <= 3 * sigma;
      if (keep[i]) ss += res[i] * res[i], ++kept;
    }
    cut.rms_mm = kept ? std::sqrt(ss / kept) : 0;
  }
  const Eigen::Vector3d n(1, -abc(1), -abc(2));
  const double tilt = std::acos(1 / n.norm()) / kDeg;
  if (!(tilt < 20)) return cut;
  cut.n = n.normalized();
  cut.d = abc(0) / n.norm();
  cut.tilt_deg = tilt;
  cut.fitted = true;
  return cut;
}

TubeBuild palm_planes(const HandFrame& H, const TubePoints& Pts, const Webs& webs, double h) {
  const std::vector<Eigen::Vector3d>& palm_pts = Pts.palm;
  const double x_end = webs.x_end, alpha_end = webs.alpha_end;
  const Eigen::Vector2d wc = webs.centre;
  TubeBuild t;
  t.id = 0;
  t.cut = fit_wrist_cut(palm_pts, H.lo.x());
  const WristCut& cut = t.cut;
  // The first station lies in the cut's plane, where it crosses the palm's mid-line.
  const double x0 = (cut.d - cut.n.y() * wc.y()) / cut.n.x();
  const int K = std::max(3, static_cast<int>(std::ceil((x_end - x0) / h)) + 1);
  const double hp = (x_end - x0) / (K - 1);
  const int fan = std::clamp(static_cast<int>(std::ceil(std::abs(alpha_end) / (2.5 * kDeg))), 1, K - 1);
  // From the cut's plane to square with the axis, at most 2.5 deg a plane as the fan at the
  // end: neighbouring planes then cross only ~85 mm from the axis, beyond the palm's edge.
  const int turn = std::min(static_cast<int>(std::ceil(cut.tilt_deg / 2.5)), std::max(0, K - 1 - fan));
  for (int k = 0; k < K; ++k) {
    const double ramp = std::clamp(static_cast<double>(k - (K - 1 - fan)) / fan, 0.0, 1.0);
    const double a = alpha_end * ramp;
    Eigen::Vector3d n(std::cos(a), std::sin(a), 0);
    if (k < turn) n = Eigen::Quaterniond::FromTwoVectors(n, cut.n).slerp(static_cast<double>(k) / turn,
                                                                          Eigen::Quaterniond::Identity()) *
                      n;
    t.st.push_back(frame_at(Eigen::Vector3d(x0 + k * hp, wc.y(), 0), n));
  }
  // No turn (no tilt, or every plane taken by the end's fan): the first plane is the cut's alone.
  if (turn == 0) t.st.front() = frame_at(t.st.front().o, cut.n);
  t.st.front().o += 1e-3 * t.st.front().n;  // the wrist cut: the first ring's slab is all on its distal side
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
  return t;
}

namespace {
constexpr double kFingerTurnRadii = 2.0;
constexpr double kMinSectionAspect = 0.55;
}  // namespace

bool SectionMiddle::round() const { return ext.minCoeff() >= kMinSectionAspect * ext.maxCoeff(); }

double SectionMiddle::offset() const {
  if (round()) return mid.norm();
  const int across = ext.x() < ext.y() ? 0 : 1;
  const double t = std::clamp(-mid(across), -0.5 * ext.maxCoeff(), 0.5 * ext.maxCoeff());
  Eigen::Vector2d q = mid;
  q(across) += t;
  return q.norm();
}

std::vector<SectionMiddle> section_middles(const TubeBuild& t, const HandFrame& H, int f) {
  // The thumb's tube starts at its base (CMC), but its metacarpal lies in the thenar, whose
  // sections (the thumb's share of the palm) have no middle the bone keeps to: even the
  // WebXR hand model's own rig lies 6-8.5 mm off there. Its phalanges are measured, as a
  // finger's are (a finger's tube starts at its MCP).
  const auto chain = finger_chain(static_cast<Finger>(f));
  const double s_from = f == 0 ? (H.J[chain[1]] - H.J[chain[0]]).norm() : 0.0;
  std::vector<SectionMiddle> mids;
  for (size_t k = 0; k < t.slab.size(); ++k) {
    const auto& g = t.slab[k];
    if (g.size() < 20 || static_cast<double>(k) * t.station_step < s_from) continue;
    Eigen::Vector2d mn = g.front(), mx = mn;
    for (const auto& p : g) mn = mn.cwiseMin(p), mx = mx.cwiseMax(p);
    mids.push_back({static_cast<int>(k), static_cast<double>(k) * t.station_step, 0.5 * (mn + mx), mx - mn, false});
  }
  // A section seen from one side only (a bent thumb's or a curled finger's far side, which
  // neither scan sees) has no middle to measure: its extent falls short across the unseen
  // side, to well under its extent along it. Only sections whose extent one way is at least
  // kMinSectionAspect of the other count (all, when fewer than 3 do): a digit's section is
  // round to oval (a thumb's ~0.75); the WebXR hand's own rig, its thumb bent 10/20/25 deg,
  // lay 4.0-4.4 mm off by the median over all its sections, the one-sided ones 0.2-0.45
  // across. A rig beside the digit keeps its full sections and their offsets.
  size_t round = 0;
  for (auto& m : mids) round += (m.counted = m.round());
  if (round < 3)
    for (auto& m : mids) m.counted = true;
  return mids;
}

TubeBuild digit_planes(const HandFrame& H, const TubePoints& Pts, int f, double h, bool thumb_turns_slowly,
                       bool to_tip_joint) {
  const auto& J = H.J;
  TubeBuild t;
  t.id = 1 + f;
  const auto chain = finger_chain(static_cast<Finger>(f));
  std::vector<Eigen::Vector3d> axis;
  for (size_t k = f == 0 ? 0 : 1; k < chain.size(); ++k) axis.push_back(J[chain[k]]);
  const Polyline pl(axis);
  const auto& pts = Pts.tube[1 + f];
  t.report.points = pts.size();
  t.report.name = skin_tube_name(1 + f);
  if (pts.size() < 50) {
    t.report.present = false;
    return t;
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
  // The digit ends where its points do; with `to_tip_joint` (a given rig) not before its tip
  // joint, which is the fingertip's end (formats/hand-rig.md): a distal phalanx curled down
  // toward the palm shows the scans its sides at grazing angles only, and a tube ending at
  // its last points stopped at the DIP (a random posture's index, MCP 27, PIP 44, DIP 22 deg,
  // on its own rig: 54 points on its distal phalanx, the tube 16 mm short; 95.5 -> 98.6 % of
  // the true skin within 1 mm). Past its points the rings are filled from the last ones
  // measured, and the dome is round. A placed skeleton's tip is the placement's guess from
  // the same points: carried past them, one such run's layout failed.
  const double s_end = to_tip_joint ? std::max(s_max, pl.s.back()) : s_max;
  const double s_c = s_end - r_tip;
  if (s_c < 2 * h) {
    t.report.present = false;
    return t;
  }
  const int K = std::max(3, static_cast<int>(std::ceil(s_c / h)) + 1);
  const double hs = s_c / (K - 1);
  // A finger's planes turn through a bent joint over ± kFingerTurnRadii tip radii, not over
  // one station: planes that turn by half the bend at once cross within a thick or curled
  // finger on the inside of the bend, where samples then fall into the wrong slab. On the
  // family study's curled hand the surface error's p95 went 0.363 -> 0.312 mm; the thumb is
  // left as it was (its wide root turning slowly cost the raised thumb 0.3 % within 1 mm).
  // With `thumb_turns_slowly` (build_skin's second try, when the thumb's tube folded) the
  // thumb's planes turn so too from its MCP on, the window growing from one station at the MCP
  // to the fingers' beyond it: a thumb whose IP is bent 45 deg folded its tube on its own true
  // rig (docs/skin.md).
  const double window = std::max(hs, kFingerTurnRadii * r_tip), s_mcp = f == 0 ? pl.s[1] : 0.0;
  for (int k = 0; k < K; ++k) {
    const double w = f != 0 ? window : thumb_turns_slowly ? std::clamp(k * hs - s_mcp, hs, window) : hs;
    Station st = frame_at(pl.at(k * hs), pl.tangent(k * hs, w));
    // A digit curled past a right angle points its far part back toward the wrist, where the
    // back of the hand projected on a station's plane points palmar: the station's v (and u)
    // turned half round from one station to the next, and the strip between their rings
    // twisted through itself (a little finger at MCP 40, PIP 45 deg folded its tube on its own
    // rig). It is kept on the side of the last station's, as a flexing finger turns its back.
    if (!t.st.empty() && st.v.dot(t.st.back().v) < 0) st.v = -st.v, st.u = -st.u;
    t.st.push_back(st);
  }
  fill_slabs(&t, pts, hs, true);
  t.station_step = hs;
  {
    const std::vector<SectionMiddle> mids = section_middles(t, H, f);
    auto median = [](std::vector<double> v) {
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      return v[v.size() / 2];
    };
    if (mids.size() >= 3) {
      std::vector<double> off, rad;
      std::vector<double> seen;
      for (const auto& m : mids) {
        if (m.counted) off.push_back(m.mid.norm()), rad.push_back(0.25 * m.ext.sum());
        seen.push_back(m.offset());
      }
      // Every section, each by what it shows (SectionMiddle::offset): the measure a given rig
      // is held to (skin_mesh.cpp, off_sections).
      t.report.axis_offset_seen_mm = median(seen);
      t.report.axis_offset_mm = median(off), t.report.section_radius_mm = median(rad);
    }
  }
  return t;
}

}  // namespace handskin::skin_steps
