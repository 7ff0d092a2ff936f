// Step 5 of the automatic skeleton (auto_rig_steps.hpp): each digit's centre line through the
// middles of its sections.
#include <algorithm>
#include <array>
#include <cmath>

#include "core/errors.hpp"
#include "skin/auto_rig_steps.hpp"
#include "skin/principal_axes.hpp"

namespace handskin::auto_rig_steps {

namespace {

// A digit's section middle more than this (mm) beside the line through those beyond it
// toward the tip is not across the digit.
constexpr double kLateralStrayMm = 1.5;
constexpr double kShortStep = 1.5;  // mm between a stub's sections along its neighbours' direction

// A finger's section centres carried toward the palm from its first one (at t = lateral's
// front), through the whole cloud `h`: every 3 mm, the finger lies between the lowest points
// of the back's profile across it (the grooves between it and its neighbours), or the gaps
// where nothing was seen, on either side of where the centres so far put it. Stops at the
// second section where no groove 1 mm deep bounds it on both sides or its width is not within
// 0.6-1.5 times the measured sections' median (the knuckles flatten into the palm's back),
// or 60 mm on. Centres are added at the front (t ascending), as (t, lateral offset, 0).
void extend_proximally(const std::vector<Eigen::Vector3d>& h, const Eigen::Vector2d& m2, const Eigen::Vector2d& d2,
                       const Eigen::Vector2d& n2, std::vector<double> widths, std::vector<Eigen::Vector3d>* lateral) {
  constexpr double kBin = 0.5, kReach = 60, kStep = 3, kGroove = 1.0;
  std::nth_element(widths.begin(), widths.begin() + widths.size() / 2, widths.end());
  const double wd = widths[widths.size() / 2], half = 1.5 * wd;
  const double t_start = lateral->front().x();
  struct Local {
    double t, l, z;
  };
  std::vector<Local> near;
  for (const auto& q : h) {
    const Eigen::Vector2d d = q.head<2>() - m2;
    const double t = d.dot(d2);
    if (t < t_start - kReach - 2 || t > t_start) continue;
    near.push_back({t, d.dot(n2), q.z()});
  }
  const int nb = static_cast<int>(std::ceil(2 * half / kBin)), inner = static_cast<int>(std::round(0.25 * wd / kBin));
  if (nb < 8) return;
  std::vector<double> top(nb);
  int misses = 0;
  for (double t = t_start - kStep; t > t_start - kReach && misses < 2; t -= kStep) {
    // The line through the centres so far predicts where the finger lies.
    double st = 0, sl = 0, stt = 0, stl = 0;
    for (const auto& c : *lateral) st += c.x(), sl += c.y(), stt += c.x() * c.x(), stl += c.x() * c.y();
    const double n = static_cast<double>(lateral->size()), den = n * stt - st * st;
    const double slope = std::abs(den) > 1e-9 ? (n * stl - st * sl) / den : 0;
    const double cp = (sl - slope * st) / n + slope * t, l0 = cp - half;
    std::fill(top.begin(), top.end(), -1e300);  // the back's height per bin; -1e300: nothing seen
    for (const Local& q : near) {
      if (std::abs(q.t - t) > 1.5 || std::abs(q.l - cp) >= half) continue;
      const int b = std::clamp(static_cast<int>((q.l - l0) / kBin), 0, nb - 1);
      top[b] = std::max(top[b], q.z);
    }
    const int cb = nb / 2;
    // The groove (or gap) on each side: the lowest bin; among empty ones, the nearest.
    auto valley = [&](int from, int to, int step) {
      int best = -1;
      for (int b = from; b != to; b += step)
        if (best < 0 || top[b] < top[best]) best = b;
      return best;
    };
    const int left = valley(cb - inner, -1, -1), right = valley(cb + inner, nb, +1);
    bool ok = left >= 0 && right >= 0;
    double ridge = -1e300;
    for (int b = left + 1; ok && b < right; ++b) ridge = std::max(ridge, top[b]);
    ok = ok && ridge > -1e299 && ridge - top[left] >= kGroove && ridge - top[right] >= kGroove;
    const double width = (right - left) * kBin;
    ok = ok && width >= 0.6 * wd && width <= 1.5 * wd;
    if (!ok) {
      ++misses;
      continue;
    }
    misses = 0;
    lateral->insert(lateral->begin(), Eigen::Vector3d(t, l0 + 0.5 * (left + right + 1) * kBin, 0));
  }
}

// A finger flexes in one plane: the vertical plane through its lateral line (`lateral_at`,
// the offset across the hand at t). Its centre line in that plane, as (t, z), traced from `c`
// along `d` (the line through its first measured centres) outward. Sections at fixed t, as
// the line's quadratic height is fitted to, cut a finger curled past ~45 deg lengthwise: its intermediate and distal
// phalanges (30-35 mm) span ~10 mm of t, and the tip was put on the DIP's knuckle (P04, PIPs
// at 55-60 deg: the little's tip 14 mm off, the skeleton refused). Every kTrackStep mm a slab
// square to the direction so far, and the centre of the section's circle in it (a curled
// finger's palmar side is seen by neither scan: the middle of a one-sided section's extent
// is its seen sheet, a circle's centre is not); the slab turned to the direction it finds,
// three times, at most kMaxTurn from the step before (at a sharp bend a slab square to the
// direction before cuts the next phalanx lengthwise). Where a slab holds fewer than 15 points
// it crosses a gap to the digit's points beyond, if any (`bridge` below); it ends where it
// finds none or has turned kMaxTotalTurn; smoothed; the last entry is the skin's tip (the
// farthest point along the last direction; over a gap, the farthest from where the first gap
// starts). Toward the back it turns kMaxDorsal at
// most: at a straight finger's tip the slab turned up round the nail and the line ran 8-20 mm
// off (the family's relaxed hands). On straight fingers it places the joints no better than
// the quadratic (six of the family's pairs: 1.30-2.88 -> 1.44-2.92 mm mean), so it is the
// skin stage's fallback when the skin refused the skeleton (CentreLines::Traced).
template <class LateralAt>
std::vector<Eigen::Vector2d> track_in_flexion_plane(const std::vector<Eigen::Vector3d>& h, const std::vector<size_t>& pts,
                                                    const Eigen::Vector2d& m2, const Eigen::Vector2d& d2,
                                                    const Eigen::Vector2d& n2, const LateralAt& lateral_at,
                                                    Eigen::Vector2d c, Eigen::Vector2d d, double window) {
  constexpr double kTrackStep = 2.0, kHalfSlab = 2.5, kMaxLength = 200, kMaxTurn = 20 * M_PI / 180,
                   kMaxTotalTurn = 150 * M_PI / 180, kMaxDorsal = 20 * M_PI / 180;
  std::vector<Eigen::Vector3d> p;  // the digit's points: (t, z, offset beside the plane)
  for (size_t i : pts) {
    const Eigen::Vector2d q = h[i].head<2>() - m2;
    const double t = q.dot(d2), off = q.dot(n2) - lateral_at(t);
    if (std::abs(off) <= window) p.emplace_back(t, h[i].z(), off);
  }
  std::vector<Eigen::Vector2d> line = {c};
  // The section's circle in a slab square to `dir` at `at` (x across, o beside the plane; its
  // centre on the plane, o = 0): x^2 + o^2 = 2 x x0 + k, linear least squares in x0 and k
  // (Kasa's fit); the centre's point, or none where the slab holds fewer than 15 points.
  const auto centre_in_slab = [&](const Eigen::Vector2d& at, const Eigen::Vector2d& dir) -> std::optional<Eigen::Vector2d> {
    const Eigen::Vector2d across(-dir.y(), dir.x());
    Eigen::Matrix2d A = Eigen::Matrix2d::Zero();
    Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
    int n = 0;
    for (const auto& q : p) {
      const Eigen::Vector2d r = q.head<2>() - at;
      const double x = r.dot(across);
      if (std::abs(r.dot(dir)) > kHalfSlab || std::abs(x) > window) continue;
      const Eigen::Vector2d row(2 * x, 1);
      A += row * row.transpose(), rhs += row * (x * x + q.z() * q.z());
      ++n;
    }
    if (n < 15) return std::nullopt;
    return Eigen::Vector2d(at + std::clamp(A.ldlt().solve(rhs)(0), -window, window) * across);
  };
  // A gap in what the scans saw. A finger curled past ~90 deg shows neither scan the sides of
  // its intermediate phalanx (they face along the hand, square to both views): the trace
  // finds its PIP's knuckle, then nothing, and well above it the nail side of the distal
  // phalanx (V1 of the probe hands, PIPs 60 and DIPs 40 deg: a 25-40 mm gap; the line ended
  // at the knuckle, the hand's scale came out 0.81 and the fingers' skin 20-45 mm short).
  // Where the slab ahead is empty: the nearest of the digit's points within kMaxGap, ahead
  // or turned toward the palm (at most kMaxBridgeTurn; toward the back kMaxDorsal), farther
  // than kOwnSurface widths from every centre traced so far (the finger's own surface: a
  // straight finger's tip cap and its palmar side lie within it), with 15 such points within
  // 2 kHalfSlab of it (a few stray returns are not a phalanx). None: the trace ends.
  constexpr double kMaxGap = 45, kMaxBridgeTurn = 150 * M_PI / 180, kOwnSurface = 0.75;
  const auto bridge = [&](const Eigen::Vector2d& at, const Eigen::Vector2d& dir) -> std::optional<Eigen::Vector2d> {
    std::vector<Eigen::Vector2d> far;
    for (const auto& q : p) {
      const Eigen::Vector2d r = q.head<2>() - at;
      const double dist = r.norm();
      if (dist > kMaxGap || dist < kTrackStep) continue;
      const double turn = std::atan2(dir.x() * r.y() - dir.y() * r.x(), dir.dot(r));
      if (turn > kMaxDorsal || turn < -kMaxBridgeTurn) continue;
      bool own = false;
      for (const auto& l : line)
        if ((q.head<2>() - l).squaredNorm() < kOwnSurface * kOwnSurface * window * window) {
          own = true;
          break;
        }
      if (!own) far.push_back(q.head<2>());
    }
    if (far.size() < 15) return std::nullopt;
    const auto nearest = *std::min_element(far.begin(), far.end(), [&](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
      return (a - at).squaredNorm() < (b - at).squaredNorm();
    });
    const auto around = std::count_if(far.begin(), far.end(), [&](const Eigen::Vector2d& q) {
      return (q - nearest).norm() <= 2 * kHalfSlab;
    });
    if (around < 15) return std::nullopt;
    return nearest;
  };
  std::optional<Eigen::Vector2d> gap_from;  // where the first gap bridged starts
  // The trace ends where it has turned by more than kMaxTotalTurn from where it started.
  const Eigen::Vector2d d_start = d;
  for (double walked = 0; walked < kMaxLength; walked += kTrackStep) {
    // The slab turned to the direction it finds, three times: at a sharp bend a slab square
    // to the direction before it cuts the next phalanx lengthwise.
    Eigen::Vector2d dir = d, next;
    bool found = true;
    for (int it = 0; it < 3 && found; ++it) {
      const auto m = centre_in_slab(c + kTrackStep * dir, dir);
      if (!m) found = false;
      else {
        next = *m;
        const Eigen::Vector2d want = (next - c).normalized();
        const double turn = std::atan2(d.x() * want.y() - d.y() * want.x(), d.dot(want));
        dir = Eigen::Rotation2Dd(std::clamp(turn, -kMaxTurn, kMaxTurn)) * d;
        // A finger bends toward the palm (-z: clockwise here); toward the back, at most
        // kMaxDorsal from where it started (the trace turned up round the nail at the tip).
        const double bent = std::atan2(d_start.x() * dir.y() - d_start.y() * dir.x(), d_start.dot(dir));
        if (bent > kMaxDorsal) dir = Eigen::Rotation2Dd(kMaxDorsal) * d_start;
      }
    }
    if (!found) {
      const auto jump = bridge(c, d);
      if (!jump) break;
      // The gap starts at the joint, a radius back from the knuckle's end: the slabs square
      // to the direction there hold the knuckle's outer cap only, and their centres run on
      // along it (V1's PIPs were put 5-6 mm beyond the joints). On from the gap's far side:
      // the next slab at the nearest point seen there.
      const Eigen::Vector2d knuckle_end = c;
      while (line.size() > 4 && (line.back() - knuckle_end).norm() < 0.5 * window) line.pop_back();
      c = line.back();
      if (!gap_from) gap_from = c;
      d = (*jump - c).normalized();
      walked += (*jump - c).norm();
      c = *jump - kTrackStep * d;
      continue;
    }
    if (std::acos(std::clamp(dir.dot(d_start), -1.0, 1.0)) > kMaxTotalTurn) break;
    d = dir;
    c = next;
    line.push_back(c);
  }
  // Smoothed (three passes of 1-2-1 weights): one-sided sections leave a zigzag of 1-3 mm
  // about the axis, which lengthened the line (and the hand's scale with it).
  for (int pass = 0; pass < 3; ++pass) {
    std::vector<Eigen::Vector2d> sm = line;
    for (size_t k = 1; k + 1 < line.size(); ++k) sm[k] = 0.25 * (line[k - 1] + 2 * line[k] + line[k + 1]);
    line.swap(sm);
  }
  if (line.size() >= 2) c = line.back(), d = (line.back() - line[line.size() - 2]).normalized();
  if (gap_from) {
    // Over a gap the far side's centres are those of one-sided sections (the distal
    // phalanx's nail side): their direction is a guess. The tip is the far side's point
    // farthest from where the gap starts, the joint before it (V1's fingertips: 2.3-8.3 mm
    // off along the last direction, 2.0-3.4 mm so), or the last centre if it lies farther.
    // But a last centre beyond every point along the line's last direction lies past the
    // skin (a slab square to a finger that points along the palm's normal holds the dome of
    // its end, and its centre ran 1.8 mm past it: R04 of scripts/random_hands_study.py --draw
    // 73, whose ring tip joint then lay on the skin and the patch layout's cap folded by 175
    // deg): then the tip is that centre moved back along the last direction to the points'
    // reach, and the centres beyond it are dropped.
    Eigen::Vector2d tip = c;
    double ahead = -1e300;
    for (const auto& q : p)
      if ((q.head<2>() - c).norm() < 2 * window) {
        ahead = std::max(ahead, (q.head<2>() - c).dot(d));
        if ((q.head<2>() - *gap_from).norm() > (tip - *gap_from).norm()) tip = q.head<2>();
      }
    if (ahead < 0 && ahead > -1e300) {
      tip = c + ahead * d;
      const double reach = (tip - *gap_from).norm();
      while (line.size() > 2 && (line.back() - *gap_from).norm() >= reach) line.pop_back();
    }
    line.push_back(tip);
  } else {
    double reach = -1e300;
    for (const auto& q : p)
      if ((q.head<2>() - c).norm() < 2 * window) reach = std::max(reach, (q.head<2>() - c).dot(d));
    line.push_back(c + std::max(reach, 0.0) * d);
  }
  return line;
}
}  // namespace

// A finger whose piece beyond the palm's opening is hardly longer than it is wide (a finger
// curled so far that seen along the palm's normal it is a stub: its tip lies over its own
// proximal phalanx) may have no direction of its own in the silhouette: its piece's principal
// axis can lie anywhere (R04 of scripts/random_hands_study.py --draw 73, its ring finger
// curled 44 deg at the MCP and 49 at the PIP: its piece 23.5 by 14.9 mm, its axis 57 deg off
// its neighbours', and the finger's joints were placed along that line, its MCP 16 mm aside
// and its tip 28 mm off). Such a finger whose axis lies more than kStrayDeg off the direction
// of its neighbours that have one on either side (interpolated by their order across the
// hand) takes that direction. Neighbouring fingers' directions differ by 15 deg in a spread
// hand, and a stub within kStrayDeg keeps its own: of draw 73's two other short ring fingers
// (R05 12 deg off, R10 22 deg), the neighbours' direction made R05's joints worse and both
// skins farther from the truth (0.174 -> 0.202 and 0.184 -> 0.205 mm). A direction from one
// side only (an edge finger, or a neighbour's that is a stub too) is not carried on: R03 of
// draw 70, its little, ring and middle fingers curled to stubs, took the index's direction
// for its ring finger and its skin went 0.430 -> 0.766 mm from the truth.
// An inner finger (middle or ring) whose axis lies more than kAcrossDeg off the mean of its two
// neighbours' axes, while those agree within kAgreeDeg, takes that mean too, however elongated
// its piece or theirs: in a relaxed curl every finger can be a stub, and a piece can be a
// sliver elongated across the hand (R06 of draw 72, every finger 22-38 deg at the MCP: the
// middle finger's piece 23.8 by 16.5 mm, its axis 78 deg off its neighbours', which agree within
// 17 deg; its joints were placed along that line, and every placement was refused, its
// proximal phalanx more than 15 mm outside the cloud). Along the neighbours' direction such a
// stub gives few sections 3 mm apart: trace_centre_line takes them kShortStep apart before it
// gives the direction up.
// Every digit's piece's principal axis (away from the palm's centre `pc`) and mean are set
// here once, for this and for trace_centre_line.
void digit_directions(const std::vector<Eigen::Vector3d>& h, const Eigen::Vector2d& pc, std::vector<Digit>* digits) {
  constexpr double kElongated = 1.6;  // length over width of a piece whose axis is the finger's
  constexpr double kStrayDeg = 30;
  constexpr double kAgreeDeg = 25, kAcrossDeg = 45;
  constexpr int kFingers = 4;         // digits[0..3]; digits[4] is the thumb
  const auto deg_between = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {  // unit vectors
    return std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * 180 / M_PI;
  };
  std::array<Eigen::Vector2d, kFingers> dir;
  std::array<bool, kFingers> own{};
  for (size_t k = 0; k < digits->size(); ++k) {
    Digit& dg = (*digits)[k];
    std::vector<Eigen::Vector2d> p2;
    for (size_t i : dg.points) p2.push_back(h[i].head<2>());
    Eigen::Matrix2d ax;
    principal_axes<2>(p2, &ax, &dg.mean);
    dg.axis = ax.col(0);
    if (dg.axis.dot(dg.mean - pc) < 0) dg.axis = -dg.axis;
    if (k >= static_cast<size_t>(kFingers)) continue;
    dir[k] = dg.axis;
    double a0 = 1e300, a1 = -1e300, b0 = 1e300, b1 = -1e300;
    for (const auto& q : p2) {
      const Eigen::Vector2d r = q - dg.mean;
      a0 = std::min(a0, r.dot(ax.col(0))), a1 = std::max(a1, r.dot(ax.col(0)));
      b0 = std::min(b0, r.dot(ax.col(1))), b1 = std::max(b1, r.dot(ax.col(1)));
    }
    own[k] = a1 - a0 >= kElongated * (b1 - b0);
  }
  for (int k = 0; k < kFingers && k < static_cast<int>(digits->size()); ++k) {
    if (own[k]) continue;
    int lo = k - 1, hi = k + 1;
    while (lo >= 0 && !own[lo]) --lo;
    while (hi < kFingers && !own[hi]) ++hi;
    if (lo < 0 || hi >= kFingers) continue;  // a direction on one side only is not carried on
    Eigen::Vector2d d =
        (static_cast<double>(hi - k) * dir[lo] + static_cast<double>(k - lo) * dir[hi]) / static_cast<double>(hi - lo);
    d.normalize();
    if (deg_between(d, dir[k]) > kStrayDeg) (*digits)[k].along = d;
  }
  // An inner finger whose neighbours on both sides agree, each with its own axis or not, and
  // whose axis lies across theirs.
  for (int k = 1; k + 1 < kFingers && k + 1 < static_cast<int>(digits->size()); ++k) {
    if ((*digits)[k].along) continue;
    const Eigen::Vector2d d = (dir[k - 1] + dir[k + 1]).normalized();
    if (deg_between(dir[k - 1], dir[k + 1]) <= kAgreeDeg && deg_between(d, dir[k]) > kAcrossDeg) (*digits)[k].along = d;
  }
}

// The digit's sections every `step` mm (3; kShortStep for a stub whose neighbours' direction
// gives too few) along its principal axis (or its neighbours' direction;
// both set by digit_directions, which runs first); their middles (the lateral offset
// a line, the height a quadratic where the digit curls) make its centre line, from well
// inside the palm to the skin's tip. `finger`: not the thumb (its line is not carried on into
// the palm between its neighbours' grooves).
void trace_centre_line(const std::vector<Eigen::Vector3d>& h, const Eigen::Vector2d& pc, bool finger, bool traced,
                       Digit* dg, double step) {
  const Eigen::Vector2d m2 = dg->mean;
  Eigen::Vector2d d2 = dg->along.value_or(dg->axis);
  if (d2.dot(m2 - pc) < 0) d2 = -d2;
  const Eigen::Vector2d n2(-d2.y(), d2.x());
  double t0 = 1e300, t1 = -1e300;
  for (size_t i : dg->points) {
    const double t = (h[i].head<2>() - m2).dot(d2);
    t0 = std::min(t0, t), t1 = std::max(t1, t);
  }
  std::vector<Eigen::Vector3d> centres;  // (t, lateral offset, z)
  std::vector<double> widths;            // each section's width across the digit
  for (double t = t0 + 2; t < t1 - 6; t += step) {
    double a = 1e300, b = -1e300, zl = 1e300, zh = -1e300;
    int n = 0;
    for (size_t i : dg->points) {
      const Eigen::Vector2d q = h[i].head<2>() - m2;
      if (std::abs(q.dot(d2) - t) > 1.5) continue;
      a = std::min(a, q.dot(n2)), b = std::max(b, q.dot(n2));
      zl = std::min(zl, h[i].z()), zh = std::max(zh, h[i].z());
      ++n;
    }
    if (n < 20) continue;
    centres.emplace_back(t, 0.5 * (a + b), 0.5 * (zl + zh));
    widths.push_back(b - a);
  }
  // Sections much narrower or wider than the digit's median are not across it: the
  // opening's remnant ends in a thin sliver along its boundary between the digits' roots,
  // and those sections' middles drew a short digit's line 20-30 deg aside (H12's little
  // finger: its PIP 11 mm off).
  if (widths.size() >= 4) {
    std::vector<double> ws = widths;
    std::nth_element(ws.begin(), ws.begin() + ws.size() / 2, ws.end());
    const double wm = ws[ws.size() / 2];
    std::vector<Eigen::Vector3d> kept_c;
    std::vector<double> kept_w;
    for (size_t k = 0; k < widths.size(); ++k)
      if (widths[k] >= 0.6 * wm && widths[k] <= 1.4 * wm) kept_c.push_back(centres[k]), kept_w.push_back(widths[k]);
    if (kept_c.size() >= 4) centres.swap(kept_c), widths.swap(kept_w);
    dg->width = wm;
  }
  // A digit does not bend sideways: from the tip's end, the centres that keep to one line.
  // The opening's remnant can carry on past the finger's root as a sliver along its
  // neighbour's boundary, of a finger's width but beside the finger's line (H12's close
  // little finger: the sliver's middles turned its line 20 deg and put its PIP 9.6 mm off).
  // The distal four start the line; each centre toward the palm joins it while it lies
  // within kLateralStrayMm of the line through those kept; the first that strays ends it.
  if (centres.size() > 4) {
    auto stray = [&](size_t first, size_t k) {  // distance of centre k from the line fitted to first..end
      double st = 0, sl = 0, stt = 0, stl = 0;
      const double n = static_cast<double>(centres.size() - first);
      for (size_t i = first; i < centres.size(); ++i) {
        st += centres[i].x(), sl += centres[i].y();
        stt += centres[i].x() * centres[i].x(), stl += centres[i].x() * centres[i].y();
      }
      const double den = n * stt - st * st;
      const double b = std::abs(den) > 1e-12 ? (n * stl - st * sl) / den : 0.0, a = (sl - b * st) / n;
      return std::abs(centres[k].y() - (a + b * centres[k].x()));
    };
    size_t first = centres.size() - 4;
    while (first > 0 && stray(first, first - 1) <= kLateralStrayMm) --first;
    if (first > 0) {
      centres.erase(centres.begin(), centres.begin() + static_cast<long>(first));
      widths.erase(widths.begin(), widths.begin() + static_cast<long>(first));
    }
  }
  if (centres.size() < 4 && dg->along) {  // along its neighbours' direction the stub gives too few sections:
    // closer sections, then its own axis
    if (step > kShortStep) return trace_centre_line(h, pc, finger, traced, dg, kShortStep);
    dg->along.reset(), dg->width = 0;
    return trace_centre_line(h, pc, finger, traced, dg);
  }
  if (centres.size() < 4) throw InputError("merged cloud", "a digit is too short to find its axis; give a rig");
  // The lateral line is fitted to these centres and to more toward the palm: the opening
  // leaves only the distal part of fingers that lie close together, and a short line
  // carried 40-60 mm into the palm strayed 5-10 mm sideways at the MCPs (H12).
  std::vector<Eigen::Vector3d> lateral = centres;
  if (finger) extend_proximally(h, m2, d2, n2, widths, &lateral);
  // Lateral offset and height as polynomials of t (least squares). Fingers flex, they do
  // not bend sideways between their joints: the lateral offset is a line; the height a
  // quadratic where the measured span is long enough to show a curl (a flexed digit arches
  // out of the hand's plane). Beyond the measured centres the curve goes on along its end
  // tangents (straight into the palm, straight to the tip).
  const double tm = 0.5 * (centres.front().x() + centres.back().x());
  const bool curl = centres.size() >= 6 && centres.back().x() - centres.front().x() >= 25;
  auto fit = [&](const std::vector<Eigen::Vector3d>& cs, int coordinate, bool quadratic) {
    // coefficients of 1, u, u² (u = t − tm)
    const int n = quadratic ? 3 : 2;
    Eigen::MatrixXd A(cs.size(), n);
    Eigen::VectorXd b(cs.size());
    for (size_t k = 0; k < cs.size(); ++k) {
      const double u = cs[k].x() - tm;
      A(k, 0) = 1, A(k, 1) = u;
      if (quadratic) A(k, 2) = u * u;
      b(k) = cs[k](coordinate);
    }
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    c.head(n) = A.colPivHouseholderQr().solve(b);
    return c;
  };
  const Eigen::Vector3d cl = fit(lateral, 1, false), cz = fit(centres, 2, curl);
  const double ta = centres.front().x(), tb = centres.back().x();
  auto point = [&](double t) {
    const double u = std::clamp(t, ta, tb) - tm, e = t - std::clamp(t, ta, tb);
    const double l = cl(0) + cl(1) * u + cl(2) * u * u + e * (cl(1) + 2 * cl(2) * u);
    const double z = cz(0) + cz(1) * u + cz(2) * u * u + e * (cz(1) + 2 * cz(2) * u);
    const Eigen::Vector2d q = m2 + t * d2 + l * n2;
    return Eigen::Vector3d(q.x(), q.y(), z);
  };
  // Asked for (`traced`, the skin stage's fallback): the finger's centre line traced in its
  // flexion plane from the line through its first four centres, which follows a finger
  // curled further than the quadratic does.
  const auto lateral_at = [&](double t) { return cl(0) + cl(1) * (t - tm); };
  std::vector<Eigen::Vector2d> traced_line;
  if (traced && dg->width > 0) {
    const Eigen::Vector3d c0 = fit({centres.begin(), centres.begin() + 4}, 2, false);
    const Eigen::Vector2d start(ta, c0(0) + c0(1) * (ta - tm)), dir = Eigen::Vector2d(1, c0(1)).normalized();
    traced_line = track_in_flexion_plane(h, dg->points, m2, d2, n2, lateral_at, start, dir, dg->width);
    if (traced_line.size() < 4) traced_line.clear();
  }
  if (!traced_line.empty()) {
    const auto at3 = [&](const Eigen::Vector2d& q) {
      const Eigen::Vector2d x = m2 + q.x() * d2 + lateral_at(q.x()) * n2;
      return Eigen::Vector3d(x.x(), x.y(), q.y());
    };
    // Into the palm straight along the traced line's first direction.
    const Eigen::Vector2d s0 = traced_line.front(), dir0 = (traced_line[3] - s0).normalized();
    for (double back = 80; back > 0; back -= 0.25) dg->curve.push_back(at3(s0 - back * dir0));
    for (const auto& q : traced_line) dg->curve.push_back(at3(q));
    dg->tip_skin = dg->curve.back();
  } else {
    // The tip: the digit's farthest point along the curve's end direction.
    const Eigen::Vector3d end = point(tb), end_dir = (point(tb + 1) - end).normalized();
    double reach = -1e300;
    for (size_t i : dg->points) reach = std::max(reach, (h[i] - end).dot(end_dir));
    dg->tip_skin = end + reach * end_dir;
    for (double t = ta - 80; t < tb; t += 0.25) dg->curve.push_back(point(t));
    dg->curve.push_back(end);
    dg->curve.push_back(dg->tip_skin);
  }
  dg->arc.assign(1, 0.0);
  for (size_t k = 1; k < dg->curve.size(); ++k) dg->arc.push_back(dg->arc.back() + (dg->curve[k] - dg->curve[k - 1]).norm());
}

}  // namespace handskin::auto_rig_steps
