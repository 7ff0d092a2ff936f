#include "synth/hand_model.hpp"

#include <algorithm>
#include <cmath>

#include "core/errors.hpp"
#include "core/hand_proportions.hpp"
#include "posture/angle_table.hpp"
#include "posture/skeleton.hpp"
#include "posture/solver.hpp"

namespace handskin {

using namespace proportions;

namespace {

constexpr double kDeg = M_PI / 180.0;

// Polynomial smooth minimum (Quilez): blends two fields over a band of width k (mm).
double smin(double a, double b, double k) {
  const double h = std::max(k - std::abs(a - b), 0.0) / k;
  return std::min(a, b) - h * h * k * 0.25;
}
double smax(double a, double b, double k) { return -smin(-a, -b, k); }

Eigen::Vector3d heading(double deg_in_plane, double deg_down = 0) {
  return {std::cos(deg_in_plane * kDeg) * std::cos(deg_down * kDeg),
          std::sin(deg_in_plane * kDeg) * std::cos(deg_down * kDeg), -std::sin(deg_down * kDeg)};
}

bool all_zero(const std::array<double, kDofCount>& a) {
  return std::all_of(a.begin(), a.end(), [](double x) { return x == 0.0; });
}

// Rotate `v` about the unit axis `a` by `deg` (Rodrigues).
Eigen::Vector3d turn(const Eigen::Vector3d& v, const Eigen::Vector3d& a, double deg) {
  return Eigen::AngleAxisd(deg * kDeg, a) * v;
}

}  // namespace

bool HandShapeOptions::IsValid(std::string* error) const {
  if (!(hand_length_mm >= 120 && hand_length_mm <= 260)) return invalid(error, "hand_length_mm must be in [120, 260]");
  if (!(finger_spread_deg >= 0 && finger_spread_deg <= 15)) return invalid(error, "finger_spread_deg must be in [0, 15]");
  if (!(thickness_scale >= 0.7 && thickness_scale <= 1.4)) return invalid(error, "thickness_scale must be in [0.7, 1.4]");
  if (!(width_scale >= 0.7 && width_scale <= 1.4)) return invalid(error, "width_scale must be in [0.7, 1.4]");
  if (!(finger_thickness_scale >= 0.7 && finger_thickness_scale <= 1.4))
    return invalid(error, "finger_thickness_scale must be in [0.7, 1.4]");
  if (!(finger_length_scale >= 0.85 && finger_length_scale <= 1.15))
    return invalid(error, "finger_length_scale must be in [0.85, 1.15]");
  if (index_ring_ratio && !(*index_ring_ratio >= 0.85 && *index_ring_ratio <= 1.05))
    return invalid(error, "index_ring_ratio must be in [0.85, 1.05]");
  if (!(thumb_abduction_deg >= 20 && thumb_abduction_deg <= 70)) return invalid(error, "thumb_abduction_deg must be in [20, 70]");
  if (forearm_mm && !(*forearm_mm >= 0 && *forearm_mm <= 40)) return invalid(error, "forearm_mm must be in [0, 40]");
  if (!(thumb_pronation_deg >= 0 && thumb_pronation_deg <= 90)) return invalid(error, "thumb_pronation_deg must be in [0, 90]");
  // Joint angles: finite, the carpus fixed, and within what a hand does (and the implicit
  // surface stays a hand: fingers curled further would fold their skin into the palm).
  for (int d = 0; d < kDofCount; ++d) {
    const DofInfo& info = dofs()[d];
    const double a = posture[d];
    if (!std::isfinite(a)) return invalid(error, "posture: " + info.name + " is not a finite number");
    if (info.kind == DofKind::Translation || info.kind == DofKind::Rotation) {
      if (a != 0) return invalid(error, "posture: " + info.name + " must be 0 (the synthetic hand stays in its frame)");
      continue;
    }
    const bool abd = info.kind == DofKind::Abduction;
    const double lo = abd ? -25 : -15, hi = abd ? 25 : 60;
    if (a < lo || a > hi)
      return invalid(error, "posture: " + info.name + " = " + std::to_string(a) + " deg is outside [" + std::to_string(int(lo)) +
                 ", " + std::to_string(int(hi)) + "] for the synthetic hand");
  }
  return true;
}

std::array<double, kDofCount> relaxed_posture(double amount) {
  std::array<double, kDofCount> a{};
  auto set = [&](const char* n, double deg) { a[dof_index(n).value()] = amount * deg; };
  // Fingers: flexion grows from the index to the little finger, as in a hand at rest.
  const char* f[] = {"index", "middle", "ring", "little"};
  const double mcp[] = {6, 8, 10, 13}, pip[] = {8, 10, 13, 15}, dip[] = {4, 6, 7, 8};
  for (int k = 0; k < 4; ++k) {
    set((std::string(f[k]) + ".mcp.flex").c_str(), mcp[k]);
    set((std::string(f[k]) + ".pip.flex").c_str(), pip[k]);
    set((std::string(f[k]) + ".dip.flex").c_str(), dip[k]);
  }
  // The thumb out of the palm plane, its tip well palmar of the finger joints.
  set("thumb.cmc.flex", 10);
  set("thumb.cmc.abd", 4);
  set("thumb.mcp.flex", 6);
  set("thumb.ip.flex", 8);
  return a;
}

double relaxed_thumb_pronation(double amount) { return 35.0 * amount; }

double Capsule::value(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  const double w = wa + t * (wb - wa), h = ha + t * (hb - ha);
  Eigen::Vector3d d = p - (a + t * ab);
  d -= dz * up;
  // Elliptic section: stretch the `up` component so the ellipse becomes a circle of radius w.
  const double z = d.dot(up);
  const Eigen::Vector3d lateral = d - z * up;
  const double dist = std::sqrt(lateral.squaredNorm() + (z * w / h) * (z * w / h));
  return dist - w;
}

double HandModel::value(const Eigen::Vector3d& p_in) const {
  if ((p_in.array() < box_min.array()).any() || (p_in.array() > box_max.array()).any()) {
    // Outside the box: a positive value that grows with distance keeps the mesher's oracle simple.
    const Eigen::Vector3d q = p_in.cwiseMax(box_min).cwiseMin(box_max);
    return 1.0 + (p_in - q).norm();
  }
  Eigen::Vector3d p = p_in;
  if (mirrored) p.y() = -p.y();  // a left hand is the right hand's mirror image: its capsules are the right hand's
  const double s = options.hand_length_mm / kNominalHandLength;
  double palm_v = 1e9;
  for (const Capsule& c : palm) palm_v = smin(palm_v, c.value(p), 12.0 * s);
  // Each finger blends into the palm, never into its neighbour: two fingers that come within
  // a few millimetres of each other stay apart (a chained blend would web them together).
  double v = palm_v;
  for (const auto& finger : fingers) {
    double f = 1e9;
    for (const Capsule& c : finger) f = smin(f, c.value(p), 2.5 * s);
    v = std::min(v, smin(palm_v, f, 6.0 * s));
  }
  return smax(v, wrist_cut_x - p.x(), 1.5 * s);
}

namespace {

// The rest (flat) skeleton: joints in the hand plane as the proportions give them, scaled by
// s (palm) and the fingers by sl·fl (the index also by index_factor); `finger_dir` gets each
// digit's phalanges' direction.
Rig rest_skeleton(const HandShapeOptions& o, double s, double sl, double fl, double index_factor,
                  std::array<Eigen::Vector3d, 5>* finger_dir) {
  auto P = [&](double x, double y, double z) { return Eigen::Vector3d(x * s, y * s, z * s); };
  Rig rest;
  rest.frame = "hand";
  rest.palm_normal = Eigen::Vector3d::UnitZ();
  rest.joints[0] = Eigen::Vector3d::Zero();
  for (int fi = 0; fi < 5; ++fi) {
    const FingerSpec& f = kFingers[fi];
    const std::vector<int> chain = finger_chain(static_cast<Finger>(fi));
    const bool thumb = fi == 0;
    const Eigen::Vector3d cmc = P(f.cmc.x(), f.cmc.y(), thumb ? -6.0 : 0.0);
    const double mc_angle = thumb ? 10.0 + o.thumb_abduction_deg : f.angle_deg;
    // The thumb sits palmar of the hand plane and points a little down out of it.
    const Eigen::Vector3d mcp = cmc + f.metacarpal * s * heading(mc_angle, thumb ? 12.0 : 0.0);
    const double ph_angle = thumb ? mc_angle - 10.0 : f.angle_deg + f.spread_steps * o.finger_spread_deg;
    const Eigen::Vector3d dir = heading(ph_angle, thumb ? 4.0 : 0.0);
    (*finger_dir)[fi] = dir;
    std::vector<double> lengths = {f.proximal, f.middle, f.distal};
    if (thumb) lengths = {f.proximal, f.distal};
    const double lf = (fi == 1 ? index_factor : 1.0) * sl * fl;  // sl == s when fl == 1
    std::vector<Eigen::Vector3d> js = {cmc, mcp};
    for (double L : lengths) js.push_back(js.back() + L * lf * dir);
    for (size_t k = 0; k < chain.size(); ++k) rest.joints[chain[k]] = js[k];
  }

  return rest;
}

// The enclosing box (capsule extents plus margin, cut at the wrist) and, for a left hand, the
// right hand's mirror image in the hand plane's long axis.
void enclose_and_mirror(const HandShapeOptions& o, HandModel* m) {
  m->box_min = Eigen::Vector3d::Constant(1e9);
  m->box_max = Eigen::Vector3d::Constant(-1e9);
  auto grow = [&](const Capsule& c) {
    const double r = std::max({c.wa, c.wb, c.ha, c.hb}) + std::abs(c.dz) + 2.0;
    for (const auto& e : {c.a, c.b}) {
      m->box_min = m->box_min.cwiseMin((e.array() - r).matrix());
      m->box_max = m->box_max.cwiseMax((e.array() + r).matrix());
    }
  };
  for (const auto& c : m->palm) grow(c);
  for (const auto& f : m->fingers)
    for (const auto& c : f) grow(c);
  m->box_min.x() = std::max(m->box_min.x(), m->wrist_cut_x - 2.0);

  // A left hand: the right hand's mirror image in the hand plane's long axis (y → −y). The
  // field mirrors its argument; the joints mirror here. palm_normal stays +Z.
  if (o.side == HandSide::Left) {
    m->mirrored = true;
    const double lo_y = m->box_min.y();
    m->box_min.y() = -m->box_max.y();
    m->box_max.y() = -lo_y;
    for (Rig* r : {&m->rig, &m->rest_rig})
      for (auto& j : r->joints) j.y() = -j.y();
  }
}

}  // namespace

HandModel build_hand_model(const HandShapeOptions& o) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("hand options", err);
  HandModel m;
  m.options = o;
  const double fl = o.finger_length_scale;
  // The scale makes the wrist-to-middle-fingertip length (flat) the one asked for.
  const double nominal = fl == 1.0 ? kNominalHandLength
                                   : kFingers[2].cmc.x() + kFingers[2].metacarpal +
                                         fl * (kFingers[2].proximal + kFingers[2].middle + kFingers[2].distal) + kTipInset;
  const double s = o.hand_length_mm / kNominalHandLength;          // palm and girth scale
  const double sl = o.hand_length_mm / nominal;                    // length scale
  const double W = s * o.width_scale, H = s * o.thickness_scale;
  const double FW = W * o.finger_thickness_scale, FH = s * o.finger_thickness_scale;
  auto P = [&](double x, double y, double z) { return Eigen::Vector3d(x * s, y * s, z * s); };
  auto capsule = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, double wa, double wb, double ha, double hb,
                     double dz) { return Capsule{a, b, wa * W, wb * W, ha * H, hb * H, dz * H}; };
  // The index's phalanges set to the asked index : ring ratio.
  const auto phalanges = [&](int fi) {
    const FingerSpec& f = kFingers[fi];
    return f.proximal + f.middle + f.distal;
  };
  const double index_factor = o.index_ring_ratio ? *o.index_ring_ratio / (phalanges(1) / phalanges(3)) : 1.0;

  // --- the rest (flat) skeleton: joints in the hand plane as the proportions give them ---
  std::array<Eigen::Vector3d, 5> finger_dir;
  m.rest_rig = rest_skeleton(o, s, sl, fl, index_factor, &finger_dir);
  const Rig& rest = m.rest_rig;
  // --- the posture: the project's skeleton, posed by forward kinematics ---
  const bool flat = all_zero(o.posture);
  std::array<Eigen::Matrix3d, kJointCount> turn_of;  // rotation of the link starting at each joint, rest → posed
  for (auto& r : turn_of) r.setIdentity();
  m.rig = rest;
  if (!flat) {
    const Skeleton sk(rest);
    const auto W0 = sk.frames(std::array<double, kDofCount>{});
    const auto Wp = sk.frames(o.posture);
    for (int j = 0; j < kJointCount; ++j) {
      m.rig.joints[j] = Wp[j].translation();
      turn_of[j] = Wp[j].linear() * W0[j].linear().transpose();
    }
  }
  Rig& rig = m.rig;

  m.fingers.resize(5);
  for (int fi = 0; fi < 5; ++fi) {
    const FingerSpec& f = kFingers[fi];
    const std::vector<int> chain = finger_chain(static_cast<Finger>(fi));
    const bool thumb = fi == 0;
    std::vector<Eigen::Vector3d> js;
    for (int j : chain) js.push_back(rig.joints[j]);
    // Each link's direction and dorsal direction in the posture; the thumb's sections turned
    // about its axis by the pronation.
    std::vector<Eigen::Vector3d> dirs, ups;
    for (size_t k = 0; k + 1 < js.size(); ++k) {
      const Eigen::Vector3d d = flat ? finger_dir[fi] : Eigen::Vector3d((js[k + 1] - js[k]).normalized());
      Eigen::Vector3d u = flat ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d(turn_of[chain[k]] * Eigen::Vector3d::UnitZ());
      if (thumb && o.thumb_pronation_deg != 0) {
        const Eigen::Vector3d axis = (js[k + 1] - js[k]).normalized();
        u = turn(u, axis, -o.thumb_pronation_deg);
      }
      dirs.push_back(d);
      ups.push_back(u);
    }
    auto blend = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
      return a == b ? a : Eigen::Vector3d((a + b).normalized());
    };

    // Phalanges: width tapers toward the tip; sections flatten toward the tip.
    const double w0 = f.width;
    const std::vector<double> widths = thumb ? std::vector<double>{w0, 0.93 * w0, 0.80 * w0}
                                             : std::vector<double>{w0, 0.91 * w0, 0.84 * w0, 0.74 * w0};
    const std::vector<double> flatness = thumb ? std::vector<double>{0.86, 0.82, 0.74}
                                               : std::vector<double>{0.90, 0.88, 0.84, 0.78};
    auto& caps = m.fingers[fi];
    for (size_t k = 1; k + 1 < js.size(); ++k) {
      Eigen::Vector3d a = js[k], b = js[k + 1];
      const double wa = widths[k - 1], wb = widths[k], ha = wa * flatness[k - 1], hb = wb * flatness[k];
      if (k + 2 == js.size()) b = b - (hb * FH - kTipInset * s) * dirs[k];  // round tip kTipInset beyond the joint
      caps.push_back(Capsule{a, b, wa * FW, wb * FW, ha * FH, hb * FH, -0.8 * FH, ups[k]});
    }
    // Knuckle pads on the back over the MCP and PIP joints (the thumb: over its IP joint).
    for (size_t k : thumb ? std::vector<size_t>{2} : std::vector<size_t>{1, 2}) {
      const double r = widths[k - 1] * 0.55;
      const Eigen::Vector3d up = blend(ups[k - 1], ups[k]), dir = blend(dirs[k - 1], dirs[k]);
      const Eigen::Vector3d c = js[k] + 0.5 * widths[k - 1] * flatness[k - 1] * FH * up;
      caps.push_back(Capsule{c - 0.5 * s * dir, c + 0.5 * s * dir, r * FW, r * FW, 0.9 * r * FW, 0.9 * r * FW, 0.0, up});
    }
    // Metacarpals build the palm (the thumb's builds the thenar eminence).
    if (thumb) {
      Capsule c = capsule(js[0], js[1], 12.0, 11.0, 11.0, 10.0, -1.0);
      c.up = ups[0];
      m.palm.push_back(c);
    } else {
      const double hw = fi == 4 ? 10.0 : 10.5;
      Capsule c = capsule(js[0], js[1], hw, hw, 13.0, 12.0, -3.0);
      c.up = ups[0];
      m.palm.push_back(c);
    }
  }
  // Carpus, forearm stub (cut flat), thenar and hypothenar eminences.
  const double cut = o.forearm_mm ? *o.forearm_mm : kWristCut * s;
  m.palm.push_back(capsule(P(6, -12, -2), P(6, 12, -2), 15.0, 15.0, 13.5, 13.5, 0.0));
  const Eigen::Vector3d forearm_end = -45.0 * s <= -(cut + 8.0) ? P(-45, 0, -1) : Eigen::Vector3d(-(cut + 8.0), 0, -1 * s);
  m.palm.push_back(capsule(forearm_end, P(4, 0, -1), 26.0, 25.0, 18.0, 16.0, 0.0));
  m.palm.push_back(capsule(P(14, 10, -7), P(44, 30, -9), 13.0, 11.0, 10.0, 9.0, 0.0));
  m.palm.push_back(capsule(P(22, -21, -6), P(62, -28, -5), 10.0, 9.0, 11.0, 10.0, 0.0));
  m.wrist_cut_x = -cut;

  enclose_and_mirror(o, &m);
  return m;
}

std::array<double, kDofCount> parse_posture(const std::string& spec, const std::vector<std::string>& sets) {
  std::array<double, kDofCount> a{};
  if (spec == "relaxed") {
    a = relaxed_posture();
  } else if (spec != "flat") {
    const AngleTable t = read_angle_table(spec);
    if (t.rows.empty()) throw InputError(spec, "no posture row");
    for (size_t c = 0; c < t.columns.size(); ++c)
      if (std::isfinite(t.rows[0][c])) a[t.columns[c]] = t.rows[0][c];
  }
  for (const std::string& s : sets) {
    int d = -1;
    double deg = 0;
    parse_assignment(s, "--set", &d, &deg, nullptr);  // the same DOF=value form as `solve --set`
    a[d] = deg;
  }
  return a;
}

}  // namespace handskin
